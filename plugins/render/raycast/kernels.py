"""The raycast renderer's per-pixel arithmetic as compiled loops (Numba): texture coordinates at
hits, bilinear albedo, surface points and normals, the lights' unshadowed irradiance, 8-bit
encoding.

Why compiled: between Embree's casts a view spent most of its time in some hundred numpy passes
over its pixels, each a trip through memory, and numpy holds the GIL between them, so the two
tile threads mostly took turns. One loop per pixel does the same work in cache and releases the
GIL (``nogil``), so tiles shade while another tile's rays are cast.

Every kernel does the float32 arithmetic of the numpy code it replaced, operation for operation
and in the same order (Numba does not contract or reorder without ``fastmath``), so images are
byte for byte what they were; ``tests/unit/test_raycast_kernels.py`` holds them to numpy
re-statements of the same formulas. Compiled once per machine and cached beside this file.
"""

from __future__ import annotations

import numpy as np
from numba import njit

F32 = np.float32
_ZERO = F32(0.0)
_ONE = F32(1.0)
_HALF = F32(0.5)
_TINY = F32(1e-12)

#: light kinds as the kernels number them
AREA, SPOT, POINT = 0, 1, 2


@njit(nogil=True, cache=True)
def interpolate_uv(face: np.ndarray, bary: np.ndarray, face_uv: np.ndarray, out: np.ndarray) -> None:
    """UV at hits (K x 2 into ``out``) from their faces' corner UVs (F x 6) and Embree's
    barycentrics (K x 2): ``w0 u0 + w1 u1 + w2 u2`` with ``w0 = 1 - w1 - w2``, in that order."""
    for k in range(face.shape[0]):
        f = face[k]
        if f < 0:  # a miss (-1): numpy's take read the last row; any row will do
            f += face_uv.shape[0]
        w1, w2 = bary[k, 0], bary[k, 1]
        w0 = (_ONE - w1) - w2
        for j in range(2):
            out[k, j] = (w0 * face_uv[f, j] + w1 * face_uv[f, 2 + j]) + w2 * face_uv[f, 4 + j]


@njit(nogil=True, cache=True)
def _corner(u: np.float32, size: np.float32) -> tuple[np.float32, np.float32]:
    # first texel (wrapped into [0, size) by float arithmetic) and the weight of the next
    f = u * size - _HALF
    x = np.floor(f)
    f = f - x
    q = np.floor(x / size) * size
    return x - q, f


@njit(nogil=True, cache=True)
def _clip_index(i: np.int64, n: int) -> np.int64:
    return 0 if i < 0 else (n - 1 if i >= n else i)


@njit(nogil=True, cache=True)
def albedo_bilinear(
    uv: np.ndarray,
    mat: np.ndarray,
    wf: np.ndarray,
    hf: np.ndarray,
    w: np.ndarray,
    h: np.ndarray,
    stride: np.ndarray,
    offset: np.ndarray,
    rgb: np.ndarray,
    alpha: np.ndarray,
    threshold: np.ndarray,
    cuts: np.ndarray,
    out: np.ndarray,
) -> None:
    """Bilinear linear albedo (K x 3 into ``out``) of hits on packed textures (see
    :class:`~agrisim.plugins.render.raycast.materials.MaterialTable`): lerp in x along both
    rows, then in y; on cut-out materials only the corners opacity keeps, weights renormalised,
    and where none does the hit's own (nearest) texel."""
    n = rgb.shape[0]
    for k in range(mat.shape[0]):
        m = mat[k]
        x0, ax = _corner(uv[k, 0], wf[m])
        y0, ay = _corner(uv[k, 1], hf[m])
        s = stride[m]
        i00 = np.int64(y0) * s + np.int64(x0) + offset[m]
        i10, i01, i11 = i00 + 1, i00 + s, i00 + s + 1
        c00, c10, c01, c11 = _clip_index(i00, n), _clip_index(i10, n), _clip_index(i01, n), _clip_index(i11, n)
        if not cuts[m]:
            for c in range(3):
                top = (rgb[c10, c] - rgb[c00, c]) * ax + rgb[c00, c]
                bottom = (rgb[c11, c] - rgb[c01, c]) * ax + rgb[c01, c]
                out[k, c] = top + (bottom - top) * ay
            continue
        t = threshold[m]
        bx, by = _ONE - ax, _ONE - ay
        k00 = F32(1.0) if alpha[c00] >= t else _ZERO
        k10 = F32(1.0) if alpha[c10] >= t else _ZERO
        k01 = F32(1.0) if alpha[c01] >= t else _ZERO
        k11 = F32(1.0) if alpha[c11] >= t else _ZERO
        q00, q10, q01, q11 = (bx * by) * k00, (ax * by) * k10, (bx * ay) * k01, (ax * ay) * k11
        total = ((q00 + q10) + q01) + q11
        if total <= _ZERO:  # no corner kept: the nearest texel, in float64 as texel_index has it
            col = np.int64(np.floor(np.float64(uv[k, 0]) * np.float64(w[m]))) % w[m]
            row = np.int64(np.floor(np.float64(uv[k, 1]) * np.float64(h[m]))) % h[m]
            i = row * s + col + offset[m]
            for c in range(3):
                out[k, c] = rgb[i, c]
            continue
        q00, q10, q01, q11 = q00 / total, q10 / total, q01 / total, q11 / total
        for c in range(3):
            out[k, c] = (((rgb[c00, c] * q00) + rgb[c10, c] * q10) + rgb[c01, c] * q01) + rgb[c11, c] * q11


@njit(nogil=True, cache=True)
def surface_frames(
    rays: np.ndarray, t: np.ndarray, face: np.ndarray, face_normal: np.ndarray, p: np.ndarray, n: np.ndarray
) -> None:
    """Hit points ``o + t d`` and the normals of the faces hit, turned to the side the camera
    sees (3 x K rows each, into ``p`` and ``n``)."""
    for k in range(t.shape[0]):
        f = face[k]
        back = _ZERO
        for j in range(3):
            p[j, k] = rays[k, 3 + j] * t[k] + rays[k, j]
            back = back + face_normal[j, f] * rays[k, 3 + j]
        for j in range(3):
            n[j, k] = -face_normal[j, f] if back > _ZERO else face_normal[j, f]


@njit(nogil=True, cache=True)
def light_weights(
    p: np.ndarray,
    n: np.ndarray,
    position: np.ndarray,
    direction: np.ndarray,
    kind: np.ndarray,
    power: np.ndarray,
    cos_inner: np.ndarray,
    cos_outer: np.ndarray,
    width: np.ndarray,
    eps: np.float32,
    w: np.ndarray,
    origins: np.ndarray,
) -> None:
    """Unshadowed scalar irradiance of each light at points ``p`` with normals ``n`` (into
    ``w``, L x K; see :meth:`~agrisim.plugins.render.raycast.lights.LightTable.weights`) and,
    when ``origins`` has columns, shadow-ray origins ``p + eps n`` (3 x K)."""
    with_origins = origins.shape[1] > 0
    for k in range(p.shape[1]):
        p0, p1, p2 = p[0, k], p[1, k], p[2, k]
        n0, n1, n2 = n[0, k], n[1, k], n[2, k]
        for i in range(position.shape[0]):
            l0, l1, l2 = position[i, 0] - p0, position[i, 1] - p1, position[i, 2] - p2
            r2 = (l0 * l0 + l1 * l1) + l2 * l2
            r2 = r2 if r2 > _TINY else _TINY
            cos_s = (n0 * l0 + n1 * l1) + n2 * l2
            cos_s = cos_s if cos_s > _ZERO else _ZERO
            cos_e = (l0 * -direction[i, 0] + l1 * -direction[i, 1]) + l2 * -direction[i, 2]
            if kind[i] == AREA:
                cos_e = cos_e if cos_e > _ZERO else _ZERO
                cos_s = cos_s * cos_e
                r2 = r2 * r2
            else:
                inv_r = _ONE / np.sqrt(r2)
                cos_s = cos_s * inv_r
                if kind[i] == SPOT:
                    x = (cos_e * inv_r - cos_outer[i]) / width[i]
                    x = _ZERO if x < _ZERO else (_ONE if x > _ONE else x)
                    cos_s = cos_s * ((x * x) * (F32(3.0) - F32(2.0) * x))
            w[i, k] = (cos_s / r2) * power[i]
        if with_origins:
            origins[0, k] = n0 * eps + p0
            origins[1, k] = n1 * eps + p1
            origins[2, k] = n2 * eps + p2


@njit(nogil=True, cache=True)
def encode_srgb8(linear: np.ndarray, out: np.ndarray, exposure: np.float32, reinhard: bool, steps: np.float32, table: np.ndarray) -> None:
    """Linear RGB (K x 3) to 8-bit sRGB (K x 3 into ``out``): times ``exposure``, optionally
    ``x / (1 + x)``, quantised to ``steps`` + 1 levels (clipped, rounded half up), looked up in
    ``table``; NaN reads level 0."""
    scale = exposure != _ONE
    top = table.shape[0] - 1
    for k in range(linear.shape[0]):
        for c in range(3):
            x = linear[k, c]
            if scale:
                x = x * exposure
            if reinhard:
                x = x / (_ONE + x)
            x = x * steps
            x = _ZERO if x < _ZERO else (steps if x > steps else x)
            x = x + _HALF
            i = 0 if x != x else min(np.int64(x), top)
            out[k, c] = table[i]
