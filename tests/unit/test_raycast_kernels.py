"""The raycast renderer's compiled loops give, bit for bit, what the vectorised numpy formulas
they replaced give (restated here, step for step, as numpy float32 evaluates them): a changed
operation order or a float64 promotion would change images."""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.plugins.render.raycast import kernels
from agrisim.plugins.render.raycast.lights import LightTable
from agrisim.plugins.render.raycast.materials import MaterialTable
from agrisim.scene.colour import ENCODE_STEPS, LINEAR_TO_SRGB8, encode_srgb8
from agrisim.scene.model import Light, Material

F32 = np.float32


def _bits_equal(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def test_interpolate_uv_matches_numpy() -> None:
    rng = np.random.default_rng(1)
    face_uv = rng.uniform(-3, 3, (50, 6)).astype(F32)
    face = rng.integers(0, 50, 10_000)
    bary = rng.uniform(0, 0.5, (10_000, 2)).astype(F32)
    out = np.empty((len(face), 2), F32)
    kernels.interpolate_uv(face, bary, face_uv, out)
    tri = face_uv[face]
    w0 = F32(1.0) - bary[:, 0]
    w0 -= bary[:, 1]
    for j in range(2):
        ref = w0 * tri[:, j]
        ref += bary[:, 0] * tri[:, 2 + j]
        ref += bary[:, 1] * tri[:, 4 + j]
        assert _bits_equal(out[:, j].copy(), ref)


def _corner(u: np.ndarray, size: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f = u * size
    f -= F32(0.5)
    x = np.floor(f)
    f -= x
    q = np.floor(x / size)
    q *= size
    x -= q
    return x, f


def _albedo_numpy(t: MaterialTable, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
    """The bilinear lookup as the numpy renderer had it (cut-out cards weighted by alpha)."""
    x0, ax = _corner(uv[:, 0], np.take(t.alb_wf, mat))
    y0, ay = _corner(uv[:, 1], np.take(t.alb_hf, mat))
    stride = np.take(t.alb_stride, mat)
    i00 = y0.astype(np.int64) * stride + x0.astype(np.int64) + np.take(t.alb_off, mat)
    i01 = i00 + stride
    c00, c10, c01, c11 = (np.take(t.alb_rgb, i, axis=0, mode="clip") for i in (i00, i00 + 1, i01, i01 + 1))
    wx = np.repeat(ax, 3).reshape(-1, 3)
    top = (c10 - c00) * wx + c00
    bottom = (c11 - c01) * wx + c01
    out = top + (bottom - top) * np.repeat(ay, 3).reshape(-1, 3)
    cut = np.flatnonzero(np.take(t.cuts, mat))
    ax, ay, i00, stride = ax[cut, None], ay[cut, None], i00[cut], stride[cut]
    threshold = np.take(t.threshold, mat[cut])
    corners = ((i00, (1 - ax) * (1 - ay)), (i00 + 1, ax * (1 - ay)), (i00 + stride, (1 - ax) * ay), (i00 + stride + 1, ax * ay))
    weights = [w * (np.take(t.alb_alpha, i, mode="clip") >= threshold)[:, None] for i, w in corners]
    total = sum(weights)
    empty = total[:, 0] <= 0
    total[empty] = 1.0
    color = np.zeros((len(cut), 3), F32)
    for (i, _), w in zip(corners, weights):
        color += np.take(t.alb_rgb, i, axis=0, mode="clip") * (w / total)
    if empty.any():
        color[empty] = np.take(t.alb_rgb, t.albedo_index(uv[cut][empty], mat[cut][empty]), axis=0)
    out[cut] = color
    return out


def test_albedo_matches_numpy_on_textures_and_cut_out_cards() -> None:
    rng = np.random.default_rng(2)
    texture = rng.integers(0, 256, (7, 5, 4), dtype=np.uint8)
    texture[..., 3] = np.where(rng.random((7, 5)) < 0.5, 0, 255)  # half the texels cut away
    table = MaterialTable()
    table.add(Material("flat", color=(0.2, 0.5, 0.9, 1.0)))
    opaque = texture.copy()
    opaque[..., 3] = 255
    table.add(Material("photo", albedo=opaque, color=(0.9, 1.0, 0.8, 1.0)))
    table.add(Material("card", albedo=texture, alpha_mode="MASK", alpha_cutoff=0.5))
    table.finish()
    assert table.cutting
    n = 20_000
    uv = rng.uniform(-2, 2, (n, 2)).astype(F32)
    uv[:100] = np.round(uv[:100] * 5) / 5  # on texel edges
    mat = rng.integers(0, 3, n).astype(np.intp)
    got = table.albedo(uv, mat, bilinear=True)
    assert _bits_equal(got, _albedo_numpy(table, uv, mat))
    # every card hit whose four corners are cut away reads its nearest texel: some must occur
    assert (np.take(table.cuts, mat)).sum() > 1000


def _weights_numpy(lights: LightTable, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    k = p.shape[1]
    w = np.empty((lights.n, k), F32)
    for i in range(lights.n):
        lv = lights.position[i][:, None] - p
        r2 = np.sum(lv * lv, axis=0)
        r2 = np.maximum(r2, F32(1e-12))
        cos_s = np.maximum(np.sum(n * lv, axis=0), F32(0.0))
        cos_e = np.sum(lv * -lights.direction[i][:, None], axis=0)
        if lights.kind[i] == "area":
            cos_s = cos_s * np.maximum(cos_e, F32(0.0))
            r2 = r2 * r2
        else:
            inv_r = 1.0 / np.sqrt(r2)
            cos_s = cos_s * inv_r
            if lights.kind[i] == "spot":
                width = max(lights.cos_inner[i] - lights.cos_outer[i], 1e-6)
                x = np.clip((cos_e * inv_r - lights.cos_outer[i]) / width, 0.0, 1.0)
                cos_s = cos_s * (x * x * (3.0 - 2.0 * x))
        w[i] = cos_s / r2 * lights.power[i]
    return w


def test_light_weights_and_shadow_origins_match_numpy() -> None:
    rng = np.random.default_rng(3)
    lights = LightTable([
        Light("a", "area", np.array([0.3, -0.2, 2.0]), np.array([0, 0.1, -1.0]), intensity=3.0, radius=0.2),
        Light("s", "spot", np.array([-1.0, 0.5, 1.5]), np.array([0.5, -0.2, -1.0]), intensity=2.0, cone_deg=30.0),
        Light("p", "point", np.array([0.0, 2.0, 1.0]), np.array([0, 0, -1.0]), (1.0, 0.8, 0.6), intensity=1.5),
    ])
    k = 30_000
    p = rng.uniform(-1, 1, (3, k)).astype(F32)
    n = rng.normal(size=(3, k))
    n = (n / np.linalg.norm(n, axis=0)).astype(F32)
    origins = np.empty((3, k), F32)
    w = lights.weights(p, n, origins=origins, eps=1e-4)
    assert _bits_equal(w, _weights_numpy(lights, p, n))
    assert _bits_equal(origins, n * F32(1e-4) + p)
    spot = w[1]
    assert (spot > 0).any() and (spot == 0).any()  # inside and outside the cone both checked


@pytest.mark.parametrize(("exposure", "tonemap"), [(1.0, "clip"), (1.7, "clip"), (0.8, "reinhard")])
def test_encode_matches_the_core_encoder(exposure: float, tonemap: str) -> None:
    rng = np.random.default_rng(4)
    linear = rng.uniform(-0.5, 3.0, (50_000, 3)).astype(F32)
    linear[:3] = [[np.nan, np.inf, -np.inf], [0.0, 1.0, 2.0], [1e-9, 0.5, 65504.0]]
    want = np.empty(linear.shape, np.uint8)
    encode_srgb8(linear.copy(), want, exposure, tonemap)
    got = np.empty(linear.shape, np.uint8)
    kernels.encode_srgb8(linear.copy(), got, F32(exposure), tonemap == "reinhard", F32(ENCODE_STEPS), LINEAR_TO_SRGB8)
    assert np.array_equal(got, want)
