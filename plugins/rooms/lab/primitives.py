"""Mesh primitives of the lab: (vertices, faces, uvs) with outward, counter-clockwise faces
and UVs laid out for tiling textures."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from agrisim.plugins.mesh_builder import Part


def quad(
    center: ArrayLike,
    a: ArrayLike,
    b: ArrayLike,
    uv_span: tuple[float, float] = (1.0, 1.0),
    uv_offset: tuple[float, float] = (0.0, 0.0),
) -> Part:
    """Rectangle ``center +- a +- b`` (half vectors) facing ``a x b``; u runs along a, and the
    image's top edge is on the ``+b`` side."""
    c, a, b = (np.asarray(t, float) for t in (center, a, b))
    V = np.array([c - a - b, c + a - b, c + a + b, c - a + b])
    su, sv = uv_span
    u0, v0 = uv_offset
    UV = np.array([[u0, v0 + sv], [u0 + su, v0 + sv], [u0 + su, v0], [u0, v0]])
    return V, np.array([[0, 1, 2], [0, 2, 3]]), UV


BOX_FACES = {  # name: (centre direction, a direction, b direction)
    "+x": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "-x": ((-1, 0, 0), (0, -1, 0), (0, 0, 1)),
    "+y": ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
    "-y": ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    "+z": ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
    "-z": ((0, 0, -1), (1, 0, 0), (0, -1, 0)),
}


def box(
    size: Sequence[float],
    center: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    repeat: tuple[float, float] | None = (1.0, 1.0),
    skip: Iterable[str] = (),
    uv_offset: tuple[float, float] = (0.0, 0.0),
) -> dict[str, Part]:
    """The faces of a box of full extents ``size``, by name (+x, -x, ...). UVs repeat every
    ``repeat`` metres (u, v) or, with ``repeat=None``, fit each face to the whole texture."""
    h = np.asarray(size, float) / 2
    c0 = np.asarray(center, float)
    out = {}
    for name, (n, a, b) in BOX_FACES.items():
        if name in skip:
            continue
        hn, ha, hb = (np.asarray(t, float) * h for t in (n, a, b))
        la, lb = 2 * np.linalg.norm(ha), 2 * np.linalg.norm(hb)
        span = (1.0, 1.0) if repeat is None else (la / repeat[0], lb / repeat[1])
        out[name] = quad(c0 + hn, ha, hb, span, uv_offset)
    return out


def ring(radius: float, n: int, seam: bool) -> np.ndarray:
    k = np.arange(n + 1 if seam else n)
    t = 2 * np.pi * k / n
    xy = radius * np.column_stack([np.cos(t), np.sin(t)])
    # exact extremes at 0, 90, 180, 270 deg so bounding boxes match the cylinder's
    if n % 4 == 0:
        quarter = k % (n // 4) == 0
        xy[quarter] = np.rint(xy[quarter] / radius) * radius
    return xy


def cylinder_side(radius: float, z0: float, z1: float, n: int, *, inward: bool = False, u_repeats: float = 1.0) -> Part:
    """The side of a z-aligned cylinder; u once (or ``u_repeats`` times) around, v from the top
    (0) to the bottom (1)."""
    xy = ring(radius, n, seam=True)
    m = n + 1
    V = np.vstack([np.column_stack([xy, np.full(m, z0)]), np.column_stack([xy, np.full(m, z1)])])
    u = np.arange(m) / n * u_repeats
    UV = np.vstack([np.column_stack([u, np.ones(m)]), np.column_stack([u, np.zeros(m)])])
    k = np.arange(n)
    b, b1, t, t1 = k, k + 1, m + k, m + k + 1
    if inward:
        F = np.vstack([np.column_stack([b, t1, b1]), np.column_stack([b, t, t1])])
    else:
        F = np.vstack([np.column_stack([b, b1, t1]), np.column_stack([b, t1, t])])
    return V, F, UV


def disc(radius: float, z: float, n: int, *, up: bool = True) -> Part:
    """A flat disc at height ``z`` facing +z (or -z); UVs map the disc's square to the texture."""
    xy = np.vstack([[0.0, 0.0], ring(radius, n, seam=False)])
    V = np.column_stack([xy, np.full(n + 1, z)])
    UV = np.column_stack([0.5 + 0.5 * xy[:, 0] / radius, 0.5 - 0.5 * xy[:, 1] / radius])
    k = np.arange(n)
    F = np.column_stack([np.zeros(n, int), 1 + k, 1 + (k + 1) % n])
    if not up:
        F = F[:, [0, 2, 1]]
    return V, F, UV


def annulus(r_in: float, r_out: float, z: float, n: int) -> Part:
    """A flat ring at height ``z`` facing +z; planar UVs over the outer disc's square."""
    outer, inner = ring(r_out, n, seam=False), ring(r_in, n, seam=False)
    xy = np.vstack([outer, inner])
    V = np.column_stack([xy, np.full(2 * n, z)])
    UV = np.column_stack([0.5 + 0.5 * xy[:, 0] / r_out, 0.5 - 0.5 * xy[:, 1] / r_out])
    k = np.arange(n)
    o, o1, i, i1 = k, (k + 1) % n, n + k, n + (k + 1) % n
    F = np.vstack([np.column_stack([o, o1, i1]), np.column_stack([o, i1, i])])
    return V, F, UV
