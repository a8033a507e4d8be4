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


#: linear in [0, 1] is quantised to ENCODE_STEPS + 1 levels before the 8-bit sRGB lookup (finer
#: than the steps of 8-bit sRGB, whose darkest are 1/3300 apart in linear light)
ENCODE_STEPS = 16383
LINEAR_TO_SRGB8 = np.round(linear_to_srgb(np.arange(ENCODE_STEPS + 1) / ENCODE_STEPS) * 255.0).astype(np.uint8)
#: pixels encoded together: the temporaries of a chunk stay in cache
_CHUNK = 1 << 15


def encode_srgb8(linear: np.ndarray, out: np.ndarray, exposure: float = 1.0, tonemap: str = "clip") -> None:
    """Linear RGB radiance (K x 3 float32) to 8-bit sRGB in ``out`` (K x 3 uint8): times
    ``exposure``, then ``clip`` (albedos stay exact up to white) or ``reinhard`` (x / (1 + x)),
    then a fine lookup table. ``linear`` is overwritten. Every renderer encodes through this (the
    raycast renderer through a compiled copy that tests hold to it byte for byte), so the same
    radiance gives the same bytes whichever drew it."""
    f32 = np.float32
    for start in range(0, len(linear), _CHUNK):
        c = slice(start, start + _CHUNK)
        x = linear[c]
        if exposure != 1.0:
            x *= f32(exposure)
        if tonemap == "reinhard":
            x /= 1.0 + x
        x *= f32(ENCODE_STEPS)
        np.clip(x, 0.0, f32(ENCODE_STEPS), out=x)
        x += f32(0.5)
        np.take(LINEAR_TO_SRGB8, x.astype(np.intp), out=out[c], mode="clip")  # (clip: not buffered)
