"""How images are encoded for disk and recordings, in one place so every writer agrees."""

from __future__ import annotations

import numpy as np


def depth_to_mm(depth: np.ndarray) -> np.ndarray:
    """Planar depth in metres (0 = no hit) to uint16 millimetres, rounded; beyond 65.535 m
    saturates. The dataset's depth PNGs and the recording's ``DepthImage`` both use this."""
    mm = np.rint(np.asarray(depth, np.float64) * 1000.0)
    return np.clip(mm, 0, 65535).astype(np.uint16)
