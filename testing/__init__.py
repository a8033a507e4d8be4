"""Helpers for testing: the contract every backend of a kind keeps (:mod:`.contracts`), and runs
perturbed as another machine would render them (:mod:`.perturb`)."""
