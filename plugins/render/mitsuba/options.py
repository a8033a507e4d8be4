"""Options of the mitsuba renderer (``[renderer.mitsuba]``)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field

from agrisim import Options


class MitsubaOptions(Options):
    """Options of the mitsuba (path tracing) renderer."""

    variant: Literal["auto", "cuda", "llvm"] = "auto"
    """Mitsuba's variant: ``cuda`` (NVIDIA GPU, OptiX), ``llvm`` (CPU, needs a shared libLLVM 15
    or newer) or ``auto`` (CUDA when a GPU is usable, else LLVM). RGB either way."""
    spp: int = Field(8, ge=1, le=1 << 16)
    """Samples per pixel (spread over the pixel's area: the box filter)."""
    sampler: Literal["multijitter", "independent"] = "multijitter"
    """How a pixel's samples are placed: ``multijitter`` (correlated multi-jittered, stratified
    in every dimension: 1.3 to 1.8 dB nearer the converged image than ``independent`` at 4 to
    16 spp on a boston fern, denoised, for 10% more GPU time) or ``independent``. Multijitter
    lays the samples on an r x ceil(spp / r) grid, r = floor(sqrt(spp)): 1, 2, 4, 8, 16, 64,
    256, 1024 are kept, others rounded up (32 -> 35, 128 -> 132, with Mitsuba's warning)."""
    denoise: Literal["auto", "on", "off"] = "auto"
    """Open Image Denoise (``pyoidn``) on the radiance, guided by the first hits' albedo and
    normal: ``auto`` denoises below 256 samples per pixel (where the noise shows) when pyoidn
    is installed."""
    max_depth: int = Field(8, ge=1, le=1024)
    """Longest path, in vertices (1: only emitters seen directly; 2: direct light only)."""
    rr_depth: int = Field(3, ge=1, le=1024)
    """Path vertex from which Russian roulette may end a path (unbiased: the converged image is
    the same). 3 against Mitsuba's 5: 23% less time on the CPU for 0.13 dB on a boston fern at
    480x270, 8 spp denoised."""
    integrator: Literal["cutout_path", "path", "volpath"] = "cutout_path"
    """``cutout_path`` (:mod:`.integrator`): path tracing whose camera, bounce and shadow rays
    pass cut-out texels exactly, as the label pass does, without spending path vertices on them;
    it gives the denoiser its guides in the same samples. Mitsuba's own for comparison: ``path``
    (cut-outs cost a vertex and block shadow rays) or ``volpath`` (null interactions, correct,
    2.2x ``path``'s time on an H100)."""
    freeze: Literal["auto", "on", "off"] = "auto"
    """Record a view's kernels once (Dr.Jit's ``dr.freeze``) and replay them for the next views,
    the camera and arms moved in place: the same images bit for bit, without tracing the render
    in Python again (an H100 at 1080p: 115 -> 15 ms a view; bench/mitsuba_frame_cost.py).
    ``auto``: on with the CUDA variant; off with LLVM, where moving the arms rebuilds Embree's
    scene, every view is recorded anew (the CPU gains nothing) and a replay can trace the scene
    before (wrong pixels: ``on`` is refused there unless the robots are hidden)."""
    exposure: float = Field(1.0, gt=0.0, le=1e6)
    """Scale of the linear radiance before tone mapping, one for the whole run (NeRF and
    photogrammetry want constant exposure). 1: a white surface lit with irradiance 1 in the
    raycast renderer's units is white."""
    tonemap: Literal["clip", "reinhard"] = "clip"
    """Linear to display, as in raycast."""
    radiance: bool = False
    """Also keep each view's linear radiance (before exposure and tone mapping, denoised when
    the RGB is): the dataset gets ``radiance/<frame>.exr``, float32 R, G, B, scaled as the RGB
    is before exposure (a white surface under irradiance 1 in raycast's units has value 1)."""
    seed: int = Field(0, ge=0, le=2**32 - 1)
    """Seed of the path sampling (mixed with the view: every view has its own noise, the same
    view always the same)."""
    envmap: Path | None = None
    """An environment map (HDR/EXR/PNG image, latitude-longitude, z up) lighting the scene from
    afar, e.g. daylight through the lab's openings; None: none."""
    envmap_scale: float = Field(1.0, gt=0.0, le=1e6)
    """Multiplies the environment map's radiance."""
    near: float = Field(1e-3, ge=0.0, le=1.0)
    """Near clipping plane (planar z), m, of the exact pass (labels and depth), as in raycast."""
    arm_triangles: int = Field(30000, ge=0, le=10_000_000)
    """Triangles per arm after decimation, as in raycast (0: as loaded)."""
