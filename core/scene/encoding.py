"""How images are encoded for disk and recordings, in one place so every writer agrees."""

from __future__ import annotations

import numpy as np


def depth_to_mm(depth: np.ndarray) -> np.ndarray:
    """Planar depth in metres (0 = no hit) to uint16 millimetres, rounded; beyond 65.535 m
    saturates. The dataset's depth PNGs and the recording's ``DepthImage`` both use this."""
    mm = np.multiply(depth, 1000.0, dtype=np.float64)  # in float64, as before rounding
    np.rint(mm, out=mm)
    np.clip(mm, 0, 65535, out=mm)
    return mm.astype(np.uint16)


def mm_to_depth(mm: np.ndarray) -> np.ndarray:
    """uint16 millimetres back to float32 metres, exactly as Open3D reads a depth PNG with
    ``depth_scale = 1000``; :func:`depth_to_mm` of the result gives ``mm`` back."""
    return np.asarray(mm).astype(np.float32) / np.float32(1000.0)


def rep118(depth: np.ndarray) -> np.ndarray:
    """Planar depth in metres as ROS's REP 118 wants it: float32, +Inf where nothing was hit
    (0 here; REP 117's "no return"). The ROS 2 bag export and the live ROS bridges publish it."""
    depth = np.asarray(depth, np.float32).copy()
    depth[depth == 0] = np.inf
    return depth
