"""Denoising of path-traced radiance with Intel Open Image Denoise (``pyoidn``, CPU or CUDA).

OIDN's ``RT`` filter is guided by the albedo and shading normal of each pixel's first hits, which keep texture
and edges sharp while the path tracer's noise goes: the ``cutout_path`` integrator returns them in
its own samples; Mitsuba's ``path`` and ``volpath`` need a second, cheap pass (the ``aov``
integrator alone, the same samples per pixel). The radiance is HDR (lamps are far brighter
than 1).
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


def _cuda_torch():  # noqa: ANN202
    """PyTorch when it can use the GPU (OIDN's CUDA device takes torch tensors), else None."""
    try:
        import torch
    except ImportError:
        return None
    return torch if torch.cuda.is_available() else None


def denoise(colour, aux) -> np.ndarray:  # noqa: ANN001 - Dr.Jit tensors or arrays
    """The denoised radiance (H x W x 3 float32) of ``colour`` (H x W x 3) guided by ``aux``
    (H x W x 6: albedo and normal, Mitsuba's ``aov`` integrator). Dr.Jit CUDA tensors are
    denoised on the GPU where PyTorch can hand them to OIDN's CUDA device without a copy
    (about 4 ms a 1080p image on an H100); anything else on the CPU."""
    pyoidn = _pyoidn()
    assert pyoidn is not None
    if "cuda" in type(colour).__module__ and _cuda_torch() is not None:
        c, a = colour.torch(), aux.torch()
        albedo, normal = a[..., 0:3].contiguous(), a[..., 3:6].contiguous()
        return (
            pyoidn.denoise(c[..., :3].contiguous(), albedo, normal, hdr=True)
            .cpu()
            .numpy()
            .astype(np.float32, copy=False)
        )
    c, a = np.asarray(colour, np.float32), np.asarray(aux, np.float32)
    albedo, normal = np.ascontiguousarray(a[..., 0:3]), np.ascontiguousarray(a[..., 3:6])
    return np.asarray(pyoidn.denoise(np.ascontiguousarray(c[..., :3]), albedo, normal, hdr=True), np.float32)
