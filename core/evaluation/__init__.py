"""Evaluation: views read back from a run, the reconstruction session and accuracy metrics."""
