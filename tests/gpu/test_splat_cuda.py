"""The ``splat`` reconstructor on a CUDA GPU (PyTorch and gsplat). Marked ``gpu``: CI has no GPU
and skips it; the GPU machine runs it from a minimal install with ``--noconftest -m gpu``.

Truths: OpenCV's projection (a tiny Gaussian's image lands where K and the pose put its
centre), and a synthetic scene whose every Gaussian is known: a textured plane of flat Gaussians
rendered from known cameras. Fitted from random Gaussians on its training views, the held-out
views come back at 35 dB or more, and the depth rendered from the fit lies on the plane (within
1 cm at 0.6 to 0.8 m: see the bias explained below; within 3 mm with the true depth in the
loss).
"""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.gpu
torch = pytest.importorskip("torch")
pytest.importorskip("gsplat")
if not torch.cuda.is_available():  # pragma: no cover - CI
    pytest.skip("PyTorch sees no CUDA GPU", allow_module_level=True)

from agrisim.plugins.recon.splat import train as gs  # noqa: E402
from agrisim.plugins.recon.splat.cameras import gsplat_camera  # noqa: E402
from agrisim.plugins.recon.splat.options import SplatOptions  # noqa: E402
from agrisim.plugins.recon.splat.quality import psnr  # noqa: E402
from agrisim.plugins.recon.splat.split import split_views  # noqa: E402
from agrisim.scene.transforms import look_at  # noqa: E402


def cuda(a: np.ndarray) -> torch.Tensor:
    return torch.as_tensor(a, dtype=torch.float32, device="cuda")


def gaussians(means: np.ndarray, log_scales: np.ndarray, colors: np.ndarray, opacity: float) -> dict:
    n = len(means)
    return {
        "means": cuda(means),
        "quats": cuda(np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))),
        "scales": cuda(log_scales),
        "opacities": cuda(np.full(n, np.log(opacity / (1 - opacity)))),
        "sh0": cuda((colors - 0.5) / gs.SH_C0)[:, None, :],
        "shN": cuda(np.zeros((n, 0, 3))),
    }


@pytest.mark.parametrize("cx, cy", [(63.5, 47.5), (60.2, 50.7)])
def test_a_tiny_gaussian_lands_on_its_opencv_pixel(cx: float, cy: float) -> None:
    K = np.array([[150.0, 0, cx], [0, 150.0, cy], [0, 0, 1]])
    T = look_at(np.array([0.3, -1.0, 1.2]), np.array([0.0, 0.0, 0.9]))
    rng = np.random.default_rng(0)
    for p in rng.uniform([-0.1, -0.1, 0.8], [0.1, 0.1, 1.0], (5, 3)):
        params = gaussians(p[None], np.log(np.full((1, 3), 0.002)), np.ones((1, 3)), 0.99)
        viewmat, Kg = gsplat_camera(K, T)
        rgb, _, _, _ = gs.render(params, cuda(viewmat), cuda(Kg), 128, 96, 0)
        img = rgb[..., 0].cpu().numpy().astype(np.float64)
        rows, cols = np.mgrid[:96, :128]
        c = (p - T[:3, 3]) @ T[:3, :3]
        u, v = K[0, 0] * c[0] / c[2] + cx, K[1, 1] * c[1] / c[2] + cy
        assert img.sum() > 0.5
        assert abs((img * cols).sum() / img.sum() - u) < 0.05 and abs((img * rows).sum() / img.sum() - v) < 0.05


def plane_depth(T: np.ndarray, K: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """(planar depth of the plane z = 0.9 at every pixel of a 128 x 96 view, whether the ray
    meets the square |x|, |y| < ``half`` there)."""
    rows, cols = np.mgrid[:96, :128]
    rays = (
        np.stack([(cols - K[0, 2]) / K[0, 0], (rows - K[1, 2]) / K[1, 1], np.ones_like(cols, float)], -1) @ T[:3, :3].T
    )
    z = (0.9 - T[2, 3]) / rays[..., 2]  # the camera-frame z of the hit (rays have camera z = 1)
    inside = (np.abs(T[0, 3] + z * rays[..., 0]) < half) & (np.abs(T[1, 3] + z * rays[..., 1]) < half)
    return z, inside


def fit_plane(depth_weight: float) -> list[tuple[float, np.ndarray]]:
    """A synthetic plane fitted from random Gaussians (with the true depth in the loss at
    ``depth_weight``): per held-out view, (PSNR, rendered minus true depth where the fit covers
    the plane)."""
    rng = np.random.default_rng(1)
    # the truth: a 0.4 m square of 6400 flat Gaussians at z = 0.9 with a smooth colour pattern
    g = (np.arange(80) + 0.5) / 80 * 0.4 - 0.2
    x, y = np.meshgrid(g, g)
    means = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 0.9)])
    colors = np.column_stack(
        [
            0.5 + 0.4 * np.sin(9 * means[:, 0]),
            0.5 + 0.4 * np.cos(7 * means[:, 1]),
            0.5 + 0.3 * np.sin(5 * (means[:, 0] + means[:, 1])),
        ]
    )
    truth = gaussians(
        means, np.log(np.column_stack([np.full(x.size, 0.004)] * 2 + [np.full(x.size, 1e-4)])), colors, 0.99
    )
    K = np.array([[120.0, 0, 63.5], [0, 120.0, 47.5], [0, 0, 1]])
    frames, poses = [], []
    for i in range(40):
        a, e = 2 * np.pi * i / 40, np.radians(35 + 20 * (i % 3))
        eye = np.array([0.7 * np.cos(a) * np.cos(e), 0.7 * np.sin(a) * np.cos(e), 0.9 + 0.7 * np.sin(e)])
        frames.append(f"v{i:02d}")
        poses.append(look_at(eye, np.array([0.0, 0.0, 0.9])))
    cams = [gsplat_camera(K, T) for T in poses]
    images = []
    for vm, Kg in cams:
        rgb, _, _, _ = gs.render(truth, cuda(vm), cuda(Kg), 128, 96, 0)
        images.append((rgb.clamp(0, 1).cpu().numpy() * 255 + 0.5).astype(np.uint8))
    train, test = split_views(frames, 0.1, 0)
    tr = [frames.index(f) for f in train]
    depths = []
    for i in tr:
        z, inside = plane_depth(poses[i], K, 0.2)
        depths.append(np.where(inside, z, 0.0).astype(np.float32))
    options = SplatOptions(
        iterations=3000, sh_degree=0, background="black", init="random", init_points=5000, depth_weight=depth_weight
    )
    init = rng.uniform([-0.25, -0.25, 0.8], [0.25, 0.25, 1.0], (5000, 3))
    splats = gs.fit(
        [images[i] for i in tr],
        np.stack([cams[i][0] for i in tr]),
        np.stack([cams[i][1] for i in tr]),
        init,
        rng.integers(0, 256, (5000, 3), dtype=np.uint8),
        1.0,
        options,
        depths=depths,
    )
    params = gs.params_from_splats(splats)
    out = []
    for f in test:
        i = frames.index(f)
        vm, Kg = cams[i]
        rgb, depth, alpha, _ = gs.render(params, cuda(vm), cuda(Kg), 128, 96, 0, depth=True)
        z, inside = plane_depth(poses[i], K, 0.19)
        sel = (alpha.cpu().numpy() > 0.99) & inside
        assert sel.sum() > 1000
        out.append((psnr(images[i] / 255.0, rgb.clamp(0, 1).cpu().numpy()), depth.cpu().numpy()[sel] - z[sel]))
    return out


def test_a_synthetic_plane_is_fitted_to_35_db_and_its_depth_lies_on_the_plane() -> None:
    plain = fit_plane(0.0)
    for quality, error in plain:
        assert quality >= 35.0
        # gsplat's expected depth gives each Gaussian its centre's depth over its whole footprint
        # and composites front to back, so on a tilted surface the nearer Gaussians weigh more:
        # measured 3 to 7 mm nearer than the plane at 0.6 to 0.8 m, more at grazing views. A
        # depth that were distance, not planar z, would be off by up to 100 mm at the corners.
        assert np.median(np.abs(error)) < 0.01 and abs(np.mean(error)) < 0.01, (
            np.median(np.abs(error)),
            np.mean(error),
        )
    # with the true depth in the loss (depth_weight), the fit's depth comes onto the plane
    supervised = fit_plane(1.0)
    for quality, error in supervised:
        assert quality >= 35.0
        assert np.median(np.abs(error)) < 0.003, np.median(np.abs(error))
    assert np.median(np.abs(np.concatenate([e for _, e in supervised]))) < 0.5 * np.median(
        np.abs(np.concatenate([e for _, e in plain]))
    )
