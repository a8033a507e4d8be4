"""Pose sources: camera poses estimated from a finished run's views (``recon.poses``)."""
