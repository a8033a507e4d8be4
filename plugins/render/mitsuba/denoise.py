"""Denoising of path-traced radiance with Intel Open Image Denoise (``pyoidn``, CPU or CUDA).

The path tracer writes, beside the radiance, the albedo and shading normal of each pixel's first
hit (Mitsuba's ``aov`` integrator); OIDN's ``RT`` filter uses them to keep texture and edges
sharp while it removes the sampling noise. The radiance is HDR (lamps are far brighter than 1).
"""

from __future__ import annotations

import logging

import numpy as np

from agrisim.errors import ConfigError

from .options import MitsubaOptions

log = logging.getLogger(__name__)

#: ``denoise = "auto"`` denoises below this many samples per pixel
AUTO_BELOW_SPP = 256
#: Mitsuba's aov integrator setting: the albedo and the shading normal of the first hit
AOVS = "albedo:albedo,nn:sh_normal"


def _pyoidn():  # noqa: ANN202
    try:
        import pyoidn
    except ImportError:
        return None
    return pyoidn


def check_denoiser() -> None:
    """Refuse ``denoise = "on"`` without pyoidn."""
    if _pyoidn() is None:
        raise ConfigError("[renderer.mitsuba] denoise = 'on' needs the package pyoidn (pip install pyoidn)")


def wanted(options: MitsubaOptions) -> bool:
    """Should this run denoise? (``auto``: below AUTO_BELOW_SPP samples, when pyoidn is here.)"""
    if options.denoise == "off":
        return False
    if options.denoise == "on":
        check_denoiser()
        return True
    if options.spp >= AUTO_BELOW_SPP:
        return False
    if _pyoidn() is None:
        log.warning("pyoidn is not installed: mitsuba renders %d spp without denoising", options.spp)
        return False
    return True


def denoise(image: np.ndarray) -> np.ndarray:
    """The denoised radiance (H x W x 3 float32) of an aov image whose channels are radiance,
    albedo and normal (H x W x 9)."""
    pyoidn = _pyoidn()
    assert pyoidn is not None
    colour, albedo, normal = (np.ascontiguousarray(image[..., i : i + 3], np.float32) for i in (0, 3, 6))
    return np.asarray(pyoidn.denoise(colour, albedo, normal, hdr=True), np.float32)
