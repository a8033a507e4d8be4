"""Reconstructors: the paper's point clouds and TSDF surfaces, per label."""
