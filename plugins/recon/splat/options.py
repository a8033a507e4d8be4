"""Options of the ``splat`` reconstructor (``[recon.splat]``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from agrisim import Options


class SplatOptions(Options):
    """Options of the ``splat`` reconstructor (3D Gaussian splatting with gsplat)."""

    iterations: int = Field(7000, ge=1, le=1_000_000)
    """Training steps, one training view each (gsplat's own trainer uses 7,000 for a quick and
    30,000 for a full fit)."""
    downscale: Literal[1, 2, 4, 8] = 1
    """Train and evaluate at 1/downscale of the run's resolution (box-averaged images, K scaled
    to match)."""
    test_fraction: float = Field(0.1, gt=0.0, lt=1.0)
    """Share of the views held out for testing, chosen at random with ``seed`` (the paper: 10%)."""
    seed: int = Field(0, ge=0, le=2**32 - 1)
    """Seed of the split, the initialisation and the training order."""
    init: Literal["depth", "random"] = "depth"
    """``depth``: Gaussians start at the training views' true depth back-projected (the run's
    own geometry, where COLMAP's sparse points would be in a photographed scene), thinned to
    ``init_points``; ``random``: uniform in the box the cameras look into."""
    init_points: int = Field(100_000, ge=100, le=10_000_000)
    """Gaussians at the start (densification and pruning then change their number)."""
    sh_degree: int = Field(3, ge=0, le=3)
    """Spherical harmonics degree of the colours (view dependence), raised one step every
    1,000 iterations as gsplat's trainer does."""
    background: Literal["random", "black", "white"] = "random"
    """Colour behind the Gaussians while training: ``random`` (a new colour every step, so that
    no Gaussian can be transparent and pass for background), or a fixed one. Evaluation renders
    on black; the lab's walls fill every view, so the background shows only where the fit has
    holes."""
    extent: Literal["cameras", "points"] = "points"
    """The scene's size, which scales the centres' learning rate and the size above which
    Gaussians are pruned: ``points``, the radius holding 95% of the initial points (the room
    around the plant, 5.7 m), or ``cameras``, 1.1 x the cameras' largest distance from their
    centroid (gsplat's trainer; 0.56 m here, which prunes the walls' Gaussians: 19.8 against
    30.1 dB held-out PSNR on indian cress at 960x540, 7,000 steps)."""
    ssim_weight: float = Field(0.2, ge=0.0, le=1.0)
    """Weight of (1 - SSIM) in the loss against the L1 term (3DGS's 0.2)."""
    depth_weight: float = Field(0.0, ge=0.0, le=100.0)
    """Weight of the run's true depth in the loss: the L1 of the rendered (expected) depth
    against it, relative to it, over the pixels where something was hit. Only a simulator has
    this depth; 0 trains on the RGB alone, as from photographs. Off by default: on coltsfoot
    (960x540, path-traced views) 0.2 brings the plant's rendered depth from 1.5 to 0.9 mm of
    the truth but costs up to 15 dB on views that face the studio lamp, whose one-sided glow
    the Gaussians cannot hold once the depth pins them to its disc (bench/splat_plant.py)."""
    plant_weight: float = Field(5.0, ge=1.0, le=1000.0)
    """Weight of the plant's pixels (label not 0) in the L1 term, the others' being 1. Besides
    the colour, it raises the plant Gaussians' screen-space gradients, which decide where
    gsplat's strategy adds Gaussians. 5 (against 1), measured alone on coltsfoot at 960x540:
    plant PSNR 31.67 -> 32.15 dB, plant centres recall@2mm 0.79 -> 0.84."""
    plant_init: float = Field(0.5, ge=0.0, le=1.0)
    """Share of the initial Gaussians (``init = "depth"``) drawn from the plant's pixels; 0
    draws from all pixels alike, which gives the plant its share of the image (4% of a
    coltsfoot view). 0.5 (against 0), measured alone on coltsfoot: plant centres recall@2mm
    0.79 -> 0.94, 0.25 dB less on the whole image."""
    absgrad: bool = False
    """Densify by the absolute screen-space gradients (AbsGS, gsplat's ``absgrad`` with its
    threshold 0.0008): gradients of opposite sign on one Gaussian, as on fine detail, no longer
    cancel. Off by default: on coltsfoot it kept fewer plant Gaussians (recall@2mm 0.82 ->
    0.75) for the same image quality."""
