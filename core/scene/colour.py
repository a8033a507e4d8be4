"""The sRGB transfer function (IEC 61966-2-1), both ways, in float64: the one definition every
renderer and plant source uses to move between stored (sRGB) and shading (linear) colours."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def srgb_to_linear(c: ArrayLike) -> np.ndarray:
    """sRGB components in 0..1 to linear."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: ArrayLike) -> np.ndarray:
    """Linear components in 0..1 to sRGB (the inverse of :func:`srgb_to_linear`)."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(np.maximum(c, 0.0031308), 1 / 2.4) - 0.055)
