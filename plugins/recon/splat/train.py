"""Fitting Gaussians to views with gsplat on one CUDA GPU, and rendering them.

The loop is gsplat's own trainer's, reduced to what agrisim needs: Adam per parameter group
with its learning rates (the centres' scaled by the scene's size and decaying to 1% over the
run), one training view per step in a seeded order, the loss (1 - w) L1 + w (1 - SSIM), the
spherical harmonics degree raised every 1,000 steps, and gsplat's ``DefaultStrategy`` for
densification and pruning.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F
from gsplat import rasterization
from gsplat.strategy import DefaultStrategy

from .options import SplatOptions

SH_C0 = 0.28209479177387814  # the degree-0 spherical harmonic: colour = SH_C0 * f_dc + 0.5


@dataclass
class Splats:
    """Trained Gaussians as NumPy arrays (gsplat's parametrisation)."""

    means: np.ndarray  # (N, 3)
    quats: np.ndarray  # (N, 4) w x y z
    log_scales: np.ndarray  # (N, 3)
    opacity_logits: np.ndarray  # (N,)
    sh0: np.ndarray  # (N, 3)
    sh_rest: np.ndarray  # (N, K, 3)
    loss: list[tuple[int, float, int]] = field(default_factory=list)  # (step, loss, Gaussians)
    seconds: float = 0.0

    @property
    def colors(self) -> np.ndarray:
        """The view-independent colour of each Gaussian, uint8 sRGB-like (as trained)."""
        return (np.clip(self.sh0 * SH_C0 + 0.5, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)

    @property
    def opacities(self) -> np.ndarray:
        return 1.0 / (1.0 + np.exp(-self.opacity_logits))


def _ssim(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """SSIM of (B, C, H, W) images with an 11 x 11 Gaussian window (sigma 1.5), valid region."""
    r = torch.arange(-5, 6, dtype=x.dtype, device=x.device)
    g = torch.exp(-(r * r) / (2 * 1.5**2))
    g = g / g.sum()
    c = x.shape[1]
    wx = g.view(1, 1, 1, 11).repeat(c, 1, 1, 1)
    wy = g.view(1, 1, 11, 1).repeat(c, 1, 1, 1)

    def blur(t: torch.Tensor) -> torch.Tensor:
        return F.conv2d(F.conv2d(t, wx, groups=c), wy, groups=c)

    mx, my = blur(x), blur(y)
    vx, vy, cov = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    c1, c2 = 0.01**2, 0.03**2
    return (((2 * mx * my + c1) * (2 * cov + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))).mean()


def _nearest_scale(points: torch.Tensor, k: int = 3, chunk: int = 4096) -> torch.Tensor:
    """Mean distance to the ``k`` nearest other points (the initial size of each Gaussian)."""
    out = torch.empty(len(points), device=points.device)
    for s in range(0, len(points), chunk):
        d = torch.cdist(points[s : s + chunk], points)
        out[s : s + chunk] = d.topk(k + 1, largest=False).values[:, 1:].mean(dim=1)
    return out.clamp_min(1e-6)


def render(
    params: dict[str, torch.Tensor],
    viewmat: torch.Tensor,
    K: torch.Tensor,
    width: int,
    height: int,
    sh_degree: int,
    background: torch.Tensor | None = None,
    depth: bool = False,
    absgrad: bool = False,
) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor, dict]:
    """(RGB H x W x 3, expected planar depth H x W or None, alpha H x W, gsplat's info) of
    one view."""
    colors, alphas, info = rasterization(
        means=params["means"],
        quats=params["quats"],
        scales=torch.exp(params["scales"]),
        opacities=torch.sigmoid(params["opacities"]),
        colors=torch.cat([params["sh0"], params["shN"]], 1),
        viewmats=viewmat[None],
        Ks=K[None],
        width=width,
        height=height,
        sh_degree=sh_degree,
        render_mode="RGB+ED" if depth else "RGB",
        packed=False,  # as gsplat's trainer; the strategy's statistics below assume it
        absgrad=absgrad,
    )
    rgb, alpha = colors[0, ..., :3], alphas[0, ..., 0]
    if background is not None:  # composited here: gsplat 1.5.3 refuses backgrounds when packed
        rgb = rgb + background * (1.0 - alpha[..., None])
    return rgb, (colors[0, ..., 3] if depth else None), alpha, info


def render_view(
    params: dict[str, torch.Tensor], viewmat: np.ndarray, K: np.ndarray, width: int, height: int, sh_degree: int
) -> tuple[np.ndarray, np.ndarray]:
    """(RGB H x W x 3 in [0, 1], expected planar depth H x W) of one view on black, as NumPy."""
    t = lambda a: torch.as_tensor(a, dtype=torch.float32, device="cuda")  # noqa: E731
    with torch.no_grad():
        rgb, depth, _, _ = render(params, t(viewmat), t(K), width, height, sh_degree, depth=True)
    assert depth is not None
    return rgb.clamp(0, 1).cpu().numpy(), depth.cpu().numpy()


def params_from_splats(splats: Splats, device: str = "cuda") -> dict[str, torch.Tensor]:
    """The tensors :func:`render` takes, from trained splats."""
    t = lambda a: torch.as_tensor(np.ascontiguousarray(a), dtype=torch.float32, device=device)  # noqa: E731
    return {
        "means": t(splats.means),
        "quats": t(splats.quats),
        "scales": t(splats.log_scales),
        "opacities": t(splats.opacity_logits),
        "sh0": t(splats.sh0)[:, None, :],
        "shN": t(splats.sh_rest),
    }


def fit(
    images: list[np.ndarray],
    viewmats: np.ndarray,
    Ks: np.ndarray,
    init_points: np.ndarray,
    init_colors: np.ndarray,
    scene_scale: float,
    options: SplatOptions,
    progress: Callable[[int, int], None] | None = None,
    depths: list[np.ndarray] | None = None,
    masks: list[np.ndarray] | None = None,
) -> Splats:
    """Train Gaussians on ``images`` (H x W x 3 uint8, gsplat cameras ``viewmats`` and ``Ks``)
    from ``init_points`` (M x 3, world) with ``init_colors`` (M x 3 uint8). ``depths`` (H x W
    planar depth, m, 0 where nothing was hit) and ``masks`` (H x W, the plant's share of each
    pixel, 0 to 1) are needed where ``options.depth_weight`` and ``options.plant_weight`` use
    them."""
    device = "cuda"
    torch.manual_seed(options.seed)
    generator = torch.Generator().manual_seed(options.seed)
    gt = [torch.as_tensor(im, device=device) for im in images]
    use_depth, use_mask = options.depth_weight > 0.0, options.plant_weight != 1.0
    if (use_depth and depths is None) or (use_mask and masks is None):
        raise ValueError("depth_weight needs the views' depths and plant_weight their plant masks")
    gt_depth = [torch.as_tensor(d, dtype=torch.float32, device=device) for d in depths] if use_depth else []
    # per-pixel L1 weights, 1 off the plant
    weights = (
        [1.0 + (options.plant_weight - 1.0) * torch.as_tensor(m, dtype=torch.float32, device=device) for m in masks]
        if use_mask
        else []
    )
    height, width = images[0].shape[:2]
    vm = torch.as_tensor(viewmats, dtype=torch.float32, device=device)
    ks = torch.as_tensor(Ks, dtype=torch.float32, device=device)

    points = torch.as_tensor(init_points, dtype=torch.float32, device=device)
    rgb = torch.as_tensor(init_colors, dtype=torch.float32, device=device) / 255.0
    n = len(points)
    k = (options.sh_degree + 1) ** 2 - 1
    lrs = {
        "means": 1.6e-4 * scene_scale,
        "scales": 5e-3,
        "quats": 1e-3,
        "opacities": 5e-2,
        "sh0": 2.5e-3,
        "shN": 2.5e-3 / 20,
    }
    params = torch.nn.ParameterDict(
        {
            "means": torch.nn.Parameter(points),
            "scales": torch.nn.Parameter(torch.log(_nearest_scale(points))[:, None].repeat(1, 3)),
            "quats": torch.nn.Parameter(torch.rand((n, 4), generator=generator).to(device)),
            "opacities": torch.nn.Parameter(torch.logit(torch.full((n,), 0.1, device=device))),
            "sh0": torch.nn.Parameter(((rgb - 0.5) / SH_C0)[:, None, :]),
            "shN": torch.nn.Parameter(torch.zeros((n, k, 3), device=device)),
        }
    )
    optimizers = {
        name: torch.optim.Adam([{"params": params[name], "lr": lr, "name": name}], eps=1e-15)
        for name, lr in lrs.items()
    }
    decay = torch.optim.lr_scheduler.ExponentialLR(optimizers["means"], gamma=0.01 ** (1.0 / options.iterations))
    strategy = (
        DefaultStrategy(verbose=False, absgrad=True, grow_grad2d=0.0008)  # AbsGS's threshold
        if options.absgrad
        else DefaultStrategy(verbose=False)
    )
    strategy.check_sanity(params, optimizers)
    state = strategy.initialize_state(scene_scale=scene_scale)

    start = time.perf_counter()
    loss_log: list[tuple[int, float, int]] = []
    order: list[int] = []
    for step in range(options.iterations):
        if not order:
            order = torch.randperm(len(gt), generator=generator).tolist()
        i = order.pop()
        target = gt[i].float() / 255.0
        if options.background == "random":
            background = torch.rand(3, generator=generator).to(device)
        else:
            background = torch.full((3,), 1.0 if options.background == "white" else 0.0, device=device)
        image, depth, _, info = render(
            params,
            vm[i],
            ks[i],
            width,
            height,
            min(step // 1000, options.sh_degree),
            background,
            depth=use_depth,
            absgrad=options.absgrad,
        )
        strategy.step_pre_backward(params, optimizers, state, step, info)
        error = (image - target).abs()
        l1 = (error * weights[i][..., None]).mean() if use_mask else error.mean()
        ssim = _ssim(image.permute(2, 0, 1)[None], target.permute(2, 0, 1)[None])
        loss = (1.0 - options.ssim_weight) * l1 + options.ssim_weight * (1.0 - ssim)
        if use_depth:
            assert depth is not None
            truth = gt_depth[i]
            hit = truth > 0
            loss = loss + options.depth_weight * ((depth[hit] - truth[hit]).abs() / truth[hit]).mean()
        loss.backward()
        for opt in optimizers.values():
            opt.step()
            opt.zero_grad(set_to_none=True)
        decay.step()
        strategy.step_post_backward(params, optimizers, state, step, info, packed=False)
        if step % 10 == 0 or step == options.iterations - 1:
            loss_log.append((step, float(loss.item()), int(len(params["means"]))))
        if progress is not None and (step % 50 == 0 or step == options.iterations - 1):
            progress(step + 1, options.iterations)
    torch.cuda.synchronize()
    seconds = time.perf_counter() - start
    host = {name: p.detach().cpu().numpy() for name, p in params.items()}
    return Splats(
        means=host["means"],
        quats=host["quats"],
        log_scales=host["scales"],
        opacity_logits=host["opacities"],
        sh0=host["sh0"][:, 0, :],
        sh_rest=host["shN"],
        loss=loss_log,
        seconds=seconds,
    )


def nearest_distances(query: np.ndarray, reference: np.ndarray, chunk: int = 8192) -> np.ndarray:
    """Distance from each query point to its nearest reference point, on the GPU."""
    if len(reference) == 0:
        return np.full(len(query), math.inf)
    ref = torch.as_tensor(reference, dtype=torch.float32, device="cuda")
    out = np.empty(len(query))
    for s in range(0, len(query), chunk):
        q = torch.as_tensor(query[s : s + chunk], dtype=torch.float32, device="cuda")
        best = torch.full((len(q),), math.inf, device="cuda")
        for r in range(0, len(ref), 1 << 16):
            best = torch.minimum(best, torch.cdist(q, ref[r : r + (1 << 16)]).min(dim=1).values)
        out[s : s + chunk] = best.cpu().numpy()
    return out
