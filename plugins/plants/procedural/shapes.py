"""Vectorised plant geometry: bent leaf cards, flat plates, solid polygon leaves and tubes.

Everything works on batches (N organs at once) so that a species with thousands of leaves builds
in milliseconds. Cards carry UVs into atlas tiles (see :mod:`.textures`): card coordinate ``t``
across (-1..1) and ``s`` along (0..1, base to tip).
"""

from __future__ import annotations

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
    hug: np.ndarray | None = None,
    bend_power: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Leaf, frond and blade cards: strips of ``segments`` quads, two across (a midrib fold).

    Each card starts at ``base`` heading at azimuth ``az`` and elevation ``elev`` and is
    ``length`` long; its width follows its tile's aspect (rects N x 4). Along the card its
    elevation falls by ``bend`` (radians, an arch; ``bend_power`` > 1 droops toward the tip),
    its heading turns by ``curl``, it rolls by ``roll`` + ``twist * s`` and its halves rise by
    ``fold`` (fraction of the half-width) along the card's normal. ``hug`` (segments + 1 values
    per card, or shared) narrows the card to hug the drawn shape, as artists cut cards to save
    overdraw; UVs narrow with it.

    Returns (vertices N x V x 3, faces F x 3, uvs N x V x 2, centrelines N x segments+1 x 3).
    """
    base = np.asarray(base, float)
    n = len(base)

    def b(x: object) -> np.ndarray:
        return np.broadcast_to(np.asarray(x, float), (n,))

    az, elev, length = b(az), b(elev), b(length)
    bend, curl, roll, twist, fold = b(bend), b(curl), b(roll), b(twist), b(fold)
    rects = np.asarray(rects, float)
    aspect = (rects[:, 3] - 1) / (rects[:, 2] - 1)
    half = 0.5 * aspect * length
    s = np.linspace(0.0, 1.0, segments + 1)
    if hug is None:
        hug_k = np.ones((n, segments + 1))
    else:
        hug_k = np.broadcast_to(np.asarray(hug, float), (n, segments + 1))
    # centreline: heading and elevation at segment midpoints, integrated
    sm = 0.5 * (s[1:] + s[:-1])
    th_m = elev[:, None] - bend[:, None] * sm[None] ** bend_power
    az_m = az[:, None] + curl[:, None] * sm[None]
    d_m = direction(az_m, th_m)  # N x S x 3
    steps = d_m * (length / segments)[:, None, None]
    P = np.concatenate([base[:, None], base[:, None] + np.cumsum(steps, axis=1)], axis=1)  # N x S+1 x 3
    th = elev[:, None] - bend[:, None] * s[None] ** bend_power
    azs = az[:, None] + curl[:, None] * s[None]
    d = direction(azs, th)
    lat = np.stack([-np.sin(azs), np.cos(azs), np.zeros_like(azs)], axis=-1)
    phi = (roll[:, None] + twist[:, None] * s[None])[..., None]
    dxl = np.cross(d, lat)
    lat_r = np.cos(phi) * lat + np.sin(phi) * dxl
    nrm = np.cross(lat_r, d)
    across = np.array([-1.0, 0.0, 1.0])
    w = (half[:, None] * hug_k)[..., None, None]  # N x S+1 x 1 x 1
    V = (
        P[:, :, None, :]
        + across[None, None, :, None] * w * lat_r[:, :, None, :]
        + (fold[:, None, None, None] * np.abs(across)[None, None, :, None] * w) * nrm[:, :, None, :]
    )
    t_uv = across[None, None, :] * hug_k[..., None]
    s_uv = np.broadcast_to(s[None, :, None], t_uv.shape)
    uv = tile_uv(rects, atlas_size, atlas_size, t_uv, s_uv)
    return V.reshape(n, -1, 3), grid_faces(segments, 2), uv.reshape(n, -1, 2), P


def plate_cards(
    centre: np.ndarray,
    normal: np.ndarray,
    spin: np.ndarray,
    size: np.ndarray,
    rects: np.ndarray,
    atlas_size: int,
    *,
    cup: np.ndarray | float = 0.0,
    anchor: float = 0.5,
    cells: int = 2,
    corner: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flat (slightly cupped) cards around ``centre`` facing ``normal``: peltate leaves, flower
    heads. ``size`` is the card's length (along ``s``); ``anchor`` is the ``s`` of the centre
    (0.5: centred, 0: the card grows from the centre). ``cup`` lifts the rim along the normal
    (fraction of the size). A (cells+1)^2 vertex grid; ``corner`` < 1 pulls the four corner
    vertices toward the middle (an octagonal card hugging a round leaf: at 0.78 a disc of
    radius 0.47 card lengths still fits). Returns (vertices, faces, uvs)."""
    centre = np.asarray(centre, float)
    n = len(centre)
    size = np.broadcast_to(np.asarray(size, float), (n,))
    cup = np.broadcast_to(np.asarray(cup, float), (n,))
    rects = np.asarray(rects, float)
    aspect = (rects[:, 3] - 1) / (rects[:, 2] - 1)
    e1, e2 = frame(normal, np.broadcast_to(np.asarray(spin, float), (n,)))
    nrm = unit(np.asarray(normal, float))
    g = np.linspace(0.0, 1.0, cells + 1)
    S, T = np.meshgrid(g, 2 * g - 1, indexing="ij")  # rows along s, cols across t
    S, T = S.ravel(), T.ravel()
    if corner != 1.0:
        at_corner = (np.abs(T) == 1.0) & (np.abs(2 * S - 1) == 1.0)
        T = np.where(at_corner, T * corner, T)
        S = np.where(at_corner, 0.5 + (S - 0.5) * corner, S)
    x = T[None] * (0.5 * aspect * size)[:, None]
    y = (S[None] - anchor) * size[:, None]
    r2 = (x**2 + y**2) / np.maximum(size[:, None] ** 2, 1e-12)
    V = (
        centre[:, None]
        + x[..., None] * e1[:, None]
        + y[..., None] * e2[:, None]
        + (cup[:, None] * size[:, None] * r2)[..., None] * nrm[:, None]
    )
    uv = tile_uv(rects, atlas_size, atlas_size, np.broadcast_to(T, (n, len(T))), np.broadcast_to(S, (n, len(S))))
    return V, grid_faces(cells, cells), uv


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
