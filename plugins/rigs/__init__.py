"""Rigs: what moves the cameras relative to the plant (``[rig] backend``)."""
