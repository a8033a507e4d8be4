"""Denoising of path-traced radiance: Intel Open Image Denoise (``pyoidn``, CPU or CUDA) or
NVIDIA's OptiX AI denoiser inside Mitsuba (CUDA variant).

OIDN's ``RT`` filter (and OptiX's, likewise) is guided by the albedo and shading normal of each pixel's first hits, which keep texture
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


def _available(denoiser: str, variant: str) -> str | None:
    """The denoiser ``denoiser`` (``auto``, ``oidn`` or ``optix``) names that can run with
    Mitsuba's ``variant``, or None."""
    cuda = variant.startswith("cuda")
    if denoiser == "oidn":
        return "oidn" if _pyoidn() is not None else None
    if denoiser == "optix":
        return "optix" if cuda else None
    return "oidn" if _pyoidn() is not None else ("optix" if cuda else None)


def _missing(denoiser: str) -> str:
    if denoiser == "optix":
        return (
            "[renderer.mitsuba] denoiser = 'optix' needs Mitsuba's CUDA variant (an NVIDIA GPU); use 'oidn' on the CPU"
        )
    if denoiser == "oidn":
        return "[renderer.mitsuba] denoiser = 'oidn' needs the package pyoidn (pip install pyoidn)"
    return "[renderer.mitsuba] denoise = 'on' needs the package pyoidn (pip install pyoidn) or Mitsuba's CUDA variant (OptiX)"


def chosen(options: MitsubaOptions, variant: str) -> str | None:
    """The denoiser this run uses, ``oidn`` or ``optix``, or None (``auto``: below
    AUTO_BELOW_SPP samples, the first of OIDN and OptiX that can run here). Refused with a
    ConfigError: ``denoise = "on"`` with none, and a ``denoiser`` named that cannot run."""
    if options.denoise == "off":
        return None
    name = _available(options.denoiser, variant)
    if name is None and (options.denoise == "on" or options.denoiser != "auto"):
        raise ConfigError(_missing(options.denoiser))
    if options.denoise == "auto" and options.spp >= AUTO_BELOW_SPP:
        return None
    if name is None:
        log.warning("no denoiser here (pyoidn, or OptiX on a GPU): mitsuba renders %d spp without one", options.spp)
    return name


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


class OptixDenoise:
    """Mitsuba's OptiX denoiser (``mi.OptixDenoiser``) guided by albedo and normals, one per
    image size; the radiance stays on the GPU until the denoised image comes back."""

    def __init__(self, mi) -> None:  # noqa: ANN001 - the mitsuba module
        self.mi = mi
        self._by_size: dict[tuple[int, int], object] = {}

    def __call__(self, colour, aux, sensor) -> np.ndarray:  # noqa: ANN001 - Dr.Jit tensors, Mitsuba's sensor
        """The denoised radiance (H x W x 3 float32) of ``colour`` guided by ``aux`` (albedo,
        then world-space normals), the normals turned into ``sensor``'s frame as OptiX wants."""
        mi = self.mi
        h, w = int(colour.shape[0]), int(colour.shape[1])
        denoiser = self._by_size.get((w, h))
        if denoiser is None:
            denoiser = self._by_size[(w, h)] = mi.OptixDenoiser(
                mi.ScalarVector2u(w, h), albedo=True, normals=True, temporal=False
            )
        out = denoiser(  # type: ignore[operator]
            colour,
            albedo=aux[..., 0:3],
            normals=aux[..., 3:6],
            to_sensor=sensor.world_transform().inverse(),
        )
        return np.asarray(out, np.float32)[..., :3]
