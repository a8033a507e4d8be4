"""Vectorised plant geometry: bent leaf cards, flat plates, solid polygon leaves and tubes.

Everything works on batches (N organs at once) so that a species with thousands of leaves builds
in milliseconds. Cards carry UVs into atlas tiles (see :mod:`.textures`): card coordinate ``t``
across (-1..1) and ``s`` along (0..1, base to tip).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from .textures import tile_uv

Z = np.array([0.0, 0.0, 1.0])


def unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-12)


def direction(az: np.ndarray, elev: np.ndarray) -> np.ndarray:
    """Unit vectors of azimuth ``az`` (about z from +x) and elevation ``elev`` (from horizontal)."""
    az, elev = np.broadcast_arrays(np.asarray(az, float), np.asarray(elev, float))
    return np.stack([np.cos(elev) * np.cos(az), np.cos(elev) * np.sin(az), np.sin(elev)], axis=-1)


def frame(normal: np.ndarray, spin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (e1, e2) spanning the plane of ``normal`` (N x 3), turned by ``spin``."""
    n = unit(np.asarray(normal, float))
    ref = np.where(np.abs(n[:, 2:3]) > 0.9, np.array([1.0, 0.0, 0.0]), Z)
    a = unit(np.cross(ref, n))
    b = np.cross(n, a)
    c, s = np.cos(spin)[:, None], np.sin(spin)[:, None]
    return c * a + s * b, -s * a + c * b


# ------------------------------------------------------------------------------- cards


def grid_faces(rows: int, cols: int) -> np.ndarray:
    """Two triangles per cell of a (rows+1) x (cols+1) vertex grid (row-major)."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = (r * (cols + 1) + c).ravel()
    b, d = a + 1, a + cols + 1
    e = d + 1
    return np.concatenate([np.stack([a, b, e], 1), np.stack([a, e, d], 1)])


#: How far a blade's triangles may stray from the smooth surface they stand for, m: half a
#: pixel of the paper's camera at 1080p from 0.3 m (818.6 px focal length: 0.37 mm a pixel).
#: Blades are subdivided until their mesh is this close to one twice as fine.
SAG = 0.18e-3


def grid_errors(coarse: np.ndarray, fine: np.ndarray) -> tuple[float, float, float]:
    """How far the triangles :func:`grid_faces` makes of ``coarse`` (N x R+1 x C+1 x 3) stray
    from ``fine``, the same surface at twice the rows and columns, off the surface (along the
    fine grid's normals: what a silhouette shows, not how the texture slides): the largest
    distance, m, at the midpoints of the edges along the rows, of those across, and of the
    cells' diagonals."""
    normals = unit(np.cross(np.gradient(fine, axis=1), np.gradient(fine, axis=2)))

    def worst(p: np.ndarray, rows: slice, cols: slice) -> float:
        off = np.sum((p - fine[:, rows, cols]) * normals[:, rows, cols], axis=-1)
        return float(np.max(np.abs(off), initial=0.0))

    along = worst(0.5 * (coarse[:, :-1] + coarse[:, 1:]), slice(1, None, 2), slice(0, None, 2))
    across = worst(0.5 * (coarse[:, :, :-1] + coarse[:, :, 1:]), slice(0, None, 2), slice(1, None, 2))
    diagonal = worst(0.5 * (coarse[:, :-1, :-1] + coarse[:, 1:, 1:]), slice(1, None, 2), slice(1, None, 2))
    return along, across, diagonal


def refined(
    surface: Callable[[int, int], np.ndarray], rows: int, cols: int, tolerance: float | None = None, limit: int = 128
) -> tuple[int, int]:
    """The (rows, cols), doubled from those given, at which the grid ``surface(rows, cols)``
    (N x rows+1 x cols+1 x 3) is within ``tolerance`` (default :data:`SAG`) of the same surface
    twice as fine: rows and columns are doubled separately, whichever strays (neither past
    ``limit``)."""
    tolerance = SAG if tolerance is None else tolerance
    while True:
        along, across, diagonal = grid_errors(surface(rows, cols), surface(2 * rows, 2 * cols))
        if max(along, across, diagonal) <= tolerance:
            return rows, cols
        more_rows = rows < limit and (along > tolerance or (diagonal > tolerance and along >= across))
        more_cols = cols < limit and (across > tolerance or (diagonal > tolerance and across >= along))
        if not (more_rows or more_cols):
            return rows, cols
        rows, cols = rows * (2 if more_rows else 1), cols * (2 if more_cols else 1)


def strip_cards(
    base: np.ndarray,
    az: np.ndarray,
    elev: np.ndarray,
    length: np.ndarray,
    rects: np.ndarray,
    atlas_size: int,
    *,
    segments: int = 4,
    bend: np.ndarray | float = 0.0,
    curl: np.ndarray | float = 0.0,
    roll: np.ndarray | float = 0.0,
    twist: np.ndarray | float = 0.0,
    fold: np.ndarray | float = 0.0,
    cup: np.ndarray | float = 0.0,
    wave: np.ndarray | float = 0.0,
    waves: float = 4.0,
    phase: np.ndarray | float = 0.0,
    bend_power: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Leaf, frond and blade cards: curved strips, subdivided until smooth (:data:`SAG`).

    Each card starts at ``base`` heading at azimuth ``az`` and elevation ``elev`` and is
    ``length`` long; its width follows its tile's aspect (rects N x 4). Along the card its
    elevation falls by ``bend`` (radians, an arch; ``bend_power`` > 1 droops toward the tip),
    its heading turns by ``curl`` and it rolls by ``roll`` + ``twist * s``. Across it the blade
    rises from the midrib along its normal, as fractions of the half-width at the margin:
    ``fold`` (a crease at the midrib, rising linearly), ``cup`` (a rounded trough, rising as the
    square of the distance) and ``wave`` (a margin rippling ``waves`` times along the blade,
    shifted by ``phase``, rising as the cube). ``segments`` is the fewest segments along; more
    are made, and more across, until the triangles are within :data:`SAG` of the surface.

    Returns (vertices N x V x 3, faces F x 3, uvs N x V x 2, centrelines N x rows+1 x 3).
    """
    base = np.asarray(base, float)
    n = len(base)

    def b(x: object) -> np.ndarray:
        return np.broadcast_to(np.asarray(x, float), (n,))

    az, elev, length = b(az), b(elev), b(length)
    bend, curl, roll, twist, fold = b(bend), b(curl), b(roll), b(twist), b(fold)
    cup, wave, phase = b(cup), b(wave), b(phase)
    rects = np.asarray(rects, float)
    half = 0.5 * (rects[:, 3] - 1) / (rects[:, 2] - 1) * length

    def centreline(rows: int) -> np.ndarray:
        """N x rows+1 x 3: the headings integrated (midpoint rule) 16 times finer than the rows
        are, so that every row count samples nearly the same curve and the refinement measures
        facets, not the integration's drift."""
        k = 16
        s = np.linspace(0.0, 1.0, k * rows + 1)
        sm = 0.5 * (s[1:] + s[:-1])
        d_m = direction(az[:, None] + curl[:, None] * sm[None], elev[:, None] - bend[:, None] * sm[None] ** bend_power)
        steps = d_m * (length / (k * rows))[:, None, None]
        return np.concatenate([base[:, None], base[:, None] + np.cumsum(steps, axis=1)], axis=1)[:, ::k]

    @functools.cache  # (refinement asks for some grids twice, and the chosen one again)
    def surface(rows: int, cols: int) -> np.ndarray:
        s = np.linspace(0.0, 1.0, rows + 1)[None, :]
        t = np.linspace(-1.0, 1.0, cols + 1)[None, None, :, None]
        azs = az[:, None] + curl[:, None] * s
        d = direction(azs, elev[:, None] - bend[:, None] * s**bend_power)
        lat = np.stack([-np.sin(azs), np.cos(azs), np.zeros_like(azs)], axis=-1)
        phi = (roll[:, None] + twist[:, None] * s)[..., None]
        lat_r = np.cos(phi) * lat + np.sin(phi) * np.cross(d, lat)
        nrm = np.cross(lat_r, d)
        ripple = np.sin(2 * np.pi * waves * s + phase[:, None]) * np.clip(s / 0.15, 0.0, 1.0)
        rise = (
            fold[:, None, None, None] * np.abs(t)
            + cup[:, None, None, None] * t**2
            + (wave[:, None] * ripple)[:, :, None, None] * np.abs(t) ** 3
        )
        w = half[:, None, None, None]
        return centreline(rows)[:, :, None] + w * (t * lat_r[:, :, None] + rise * nrm[:, :, None])

    rows, cols = refined(surface, max(1, int(segments)), 2)
    V = surface(rows, cols)
    t_uv = np.broadcast_to(np.linspace(-1.0, 1.0, cols + 1)[None, None, :], (n, rows + 1, cols + 1))
    s_uv = np.broadcast_to(np.linspace(0.0, 1.0, rows + 1)[None, :, None], t_uv.shape)
    uv = tile_uv(rects, atlas_size, atlas_size, t_uv, s_uv)
    # wound so that the faces' normal is the side an arching blade turns up (-nrm): its front,
    # where the texture's relief rises and the upper side's colour is
    return V.reshape(n, -1, 3), grid_faces(rows, cols)[:, ::-1], uv.reshape(n, -1, 2), centreline(rows)


def plate_cards(
    centre: np.ndarray,
    normal: np.ndarray,
    spin: np.ndarray,
    size: np.ndarray,
    rects: np.ndarray,
    atlas_size: int,
    *,
    cup: np.ndarray | float = 0.0,
    wave: np.ndarray | float = 0.0,
    waves: float = 7.0,
    phase: np.ndarray | float = 0.0,
    droop: np.ndarray | float = 0.0,
    anchor: float = 0.5,
    cells: int = 2,
    corner: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cards around ``centre`` facing ``normal``, curved: peltate and heart-shaped leaves,
    flower heads. ``size`` is the card's length (along ``s``); ``anchor`` is the ``s`` of the
    centre (0.5: centred, 0: the card grows from the centre). Along the normal, as fractions of
    the size: ``cup`` lifts the rim as the square of the distance from the centre, ``wave``
    ripples it ``waves`` times around (shifted by ``phase``) as the cube, and ``droop`` lowers
    the half beyond the centre (the tip) as the square. ``cells`` is the fewest cells a side;
    more are made until the triangles are within :data:`SAG` of the surface. ``corner`` < 1
    draws the card in onto an octagon whose corners are cut through (corner, corner) of the
    square's (-1..1) half-widths (a card hugging a round leaf: at 0.78 a disc of radius 0.47
    card lengths still fits, at 0.7 too); the texture follows, so nothing drawn moves. Returns (vertices, faces, uvs)."""
    centre = np.asarray(centre, float)
    n = len(centre)

    def b(x: object) -> np.ndarray:
        return np.broadcast_to(np.asarray(x, float), (n,))

    size, cup, wave, phase, droop = b(size), b(cup), b(wave), b(phase), b(droop)
    rects = np.asarray(rects, float)
    aspect = (rects[:, 3] - 1) / (rects[:, 2] - 1)
    e1, e2 = frame(normal, b(spin))
    nrm = unit(np.asarray(normal, float))

    def params(rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
        S, T = np.meshgrid(np.linspace(0.0, 1.0, rows + 1), np.linspace(-1.0, 1.0, cols + 1), indexing="ij")
        if corner != 1.0:  # the square drawn in toward its middle onto the octagon
            Y = 2 * S - 1
            edge = np.maximum(np.abs(T), np.abs(Y))
            k = edge / np.maximum(np.maximum(edge, (np.abs(T) + np.abs(Y)) / (2 * corner)), 1e-12)
            T, S = T * k, 0.5 + 0.5 * Y * k
        return S, T

    @functools.cache  # (refinement asks for some grids twice, and the chosen one again)
    def surface(rows: int, cols: int) -> np.ndarray:
        S, T = params(rows, cols)
        x = T[None] * (0.5 * aspect * size)[:, None, None]
        y = (S[None] - anchor) * size[:, None, None]
        u, v = x / size[:, None, None], y / size[:, None, None]
        r = np.hypot(u, v)
        lift = (
            cup[:, None, None] * r**2
            + wave[:, None, None] * r**3 * np.sin(waves * np.arctan2(u, v) + phase[:, None, None])
            - droop[:, None, None] * np.maximum(v, 0.0) ** 2
        ) * size[:, None, None]
        return (
            centre[:, None, None]
            + x[..., None] * e1[:, None, None]
            + y[..., None] * e2[:, None, None]
            + lift[..., None] * nrm[:, None, None]
        )

    rows, cols = refined(surface, max(1, int(cells)), max(1, int(cells)))
    S, T = params(rows, cols)
    uv = tile_uv(
        rects, atlas_size, atlas_size, np.broadcast_to(T.ravel(), (n, T.size)), np.broadcast_to(S.ravel(), (n, S.size))
    )
    return surface(rows, cols).reshape(n, -1, 3), grid_faces(rows, cols), uv


def solid_leaves(
    centre: np.ndarray,
    normal: np.ndarray,
    spin: np.ndarray,
    length: np.ndarray,
    width: np.ndarray,
    rects: np.ndarray,
    atlas_size: int,
    *,
    ring: int = 8,
    fold: np.ndarray | float = 0.15,
    inset: float = 0.94,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Small solid leaves as real polygons: a fan of ``ring`` triangles whose outline lies just
    inside the ellipse drawn in the leaf's tile (so opacity cuts almost nothing). The leaf's
    base is at ``centre``, it points along ``spin`` in the plane of ``normal``, its midrib is
    raised by ``fold`` x width. Returns (vertices, faces, uvs)."""
    centre = np.asarray(centre, float)
    n = len(centre)
    e1, e2 = frame(normal, np.broadcast_to(np.asarray(spin, float), (n,)))
    nrm = unit(np.asarray(normal, float))
    length = np.broadcast_to(np.asarray(length, float), (n,))
    width = np.broadcast_to(np.asarray(width, float), (n,))
    fold = np.broadcast_to(np.asarray(fold, float), (n,))
    a = np.linspace(0, 2 * np.pi, ring, endpoint=False)
    # outline in card coordinates: ellipse centred at s = 0.5, t in [-1, 1]
    t = np.concatenate([[0.0], inset * np.cos(a)])
    s = np.concatenate([[0.5], 0.5 + 0.5 * inset * np.sin(a)])
    x = t[None] * (0.5 * width)[:, None]
    y = s[None] * length[:, None]
    lift = (1.0 - np.abs(t))[None] * (fold * width)[:, None]
    V = centre[:, None] + x[..., None] * e1[:, None] + y[..., None] * e2[:, None] + lift[..., None] * nrm[:, None]
    faces = np.stack([np.zeros(ring, int), 1 + np.arange(ring), 1 + (np.arange(ring) + 1) % ring], axis=1)
    uv = tile_uv(
        np.asarray(rects, float),
        atlas_size,
        atlas_size,
        np.broadcast_to(t, (n, len(t))),
        np.broadcast_to(s, (n, len(s))),
    )
    return V, faces, uv


# ------------------------------------------------------------------------------- tubes


def bezier(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, count: int) -> np.ndarray:
    """Cubic Bézier curves (N x 3 control points each) sampled at ``count`` points: N x count x 3."""
    u = np.linspace(0.0, 1.0, count)[None, :, None]
    p0, p1, p2, p3 = (np.asarray(p, float)[:, None] for p in (p0, p1, p2, p3))
    return (1 - u) ** 3 * p0 + 3 * (1 - u) ** 2 * u * p1 + 3 * (1 - u) * u**2 * p2 + u**3 * p3


def tubes(path: np.ndarray, radius: np.ndarray | float, sides: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Open tubes along polylines ``path`` (N x P x 3) of ``radius`` (scalar, N, or N x P),
    with parallel-transported frames (no twisting). Returns (vertices N x P*sides x 3, faces)."""
    path = np.asarray(path, float)
    n, p = path.shape[:2]
    r = np.broadcast_to(
        np.asarray(radius, float).reshape((-1, 1) if np.ndim(radius) == 1 else np.shape(radius)), (n, p)
    )
    tan = np.gradient(path, axis=1)
    tan = unit(tan)
    ref = np.where(np.abs(tan[:, 0, 2:3]) > 0.9, np.array([1.0, 0.0, 0.0]), Z)
    nrm = np.empty_like(path)
    nrm[:, 0] = unit(np.cross(tan[:, 0], ref))
    for k in range(1, p):  # parallel transport
        v = nrm[:, k - 1] - np.sum(nrm[:, k - 1] * tan[:, k], axis=1, keepdims=True) * tan[:, k]
        nrm[:, k] = unit(v)
    bin_ = np.cross(tan, nrm)
    a = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    ring = np.cos(a)[None, None, :, None] * nrm[:, :, None] + np.sin(a)[None, None, :, None] * bin_[:, :, None]
    V = path[:, :, None] + r[..., None, None] * ring
    k, j = np.meshgrid(np.arange(p - 1), np.arange(sides), indexing="ij")
    a0 = (k * sides + j).ravel()
    a1 = (k * sides + (j + 1) % sides).ravel()
    b0, b1 = a0 + sides, a1 + sides
    faces = np.concatenate([np.stack([a0, a1, b1], 1), np.stack([a0, b1, b0], 1)])
    return V.reshape(n, -1, 3), faces
