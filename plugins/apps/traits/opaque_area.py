"""The exact opaque area of every triangle of a mesh: the part of its surface whose texel, looked
up as every renderer of agrisim looks it up (nearest, wrapping: :mod:`agrisim.scene.texturing`),
survives the material's alpha cut-off.

A triangle's UV image is cut by the texel grid into convex pieces, one per texel it touches
(Sutherland-Hodgman clipping against the texel's four edges); the opaque pieces' UV area,
scaled by the triangle's 3D-to-UV area ratio (the map is affine on a triangle), is its opaque
area. Exact up to floating point: no sampling, no rasterisation. A cut-out leaf card counts its
leaf, not its rectangle.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from agrisim.scene.model import Material, Mesh
from agrisim.scene.texturing import alpha_threshold

#: (triangle, texel) pieces clipped at once: bounds the working memory (about 200 bytes each)
CHUNK = 1 << 18
#: vertices a triangle clipped by a rectangle can have (3 + one per edge cut)
_MAX_VERTICES = 7


@dataclass
class OpaquePieces:
    """The opaque surface of a mesh as convex planar pieces, one per (triangle, texel) it
    keeps; a triangle whose material cuts nothing is one piece. World (or the mesh's) frame."""

    face: np.ndarray
    """(K,) the triangle each piece lies on"""
    area: np.ndarray
    """(K,) m^2"""
    centroid: np.ndarray
    """(K, 3) each piece's centre of area"""
    vertices: np.ndarray
    """(K, 7, 3) each piece's corners, the first ``count`` of them"""
    count: np.ndarray
    """(K,) corners of each piece (3 to 7)"""

    def corners(self) -> np.ndarray:
        """(sum(count), 3) every piece's corners: where the opaque surface ends."""
        return self.vertices[np.arange(_MAX_VERTICES)[None, :] < self.count[:, None]]


def kept_texels(material: Material, labels: frozenset[int] | None = None) -> np.ndarray | bool:
    """Which texels of ``material`` count: H x W bool where a texture decides, else one bool for
    the whole material. Opacity keeps a texel (glTF alpha x colour factor >= cut-off, as every
    renderer looks it up) and, given ``labels``, its label is one of them."""
    keep: np.ndarray | bool = True
    if material.cuts:
        threshold = alpha_threshold(material)
        keep = threshold == 0 if material.albedo is None else np.asarray(material.albedo)[..., 3] >= threshold
    if labels is not None:
        if material.labels is None:
            keep = keep & (material.label in labels)
        else:
            named = np.isin(np.asarray(material.labels), sorted(labels))
            if isinstance(keep, np.ndarray) and keep.shape != named.shape:
                # (one texel grid cuts the triangles: the two textures must share it)
                raise ValueError(f"material {material.name!r}: its label texture and its albedo differ in size")
            keep = keep & named
    return keep if isinstance(keep, np.ndarray) else bool(keep)


def opaque_pieces(
    mesh: Mesh, labels: frozenset[int] | None = None, faces: np.ndarray | None = None
) -> Iterator[OpaquePieces]:
    """The opaque surface of ``mesh`` (of ``faces`` only, when given), restricted to texels of
    ``labels`` when given, as :class:`OpaquePieces` in chunks (a fine atlas cuts a plant into
    millions of pieces: reduce them as they come)."""
    chosen = np.arange(len(mesh.faces)) if faces is None else np.asarray(faces, np.int64)
    for index, material in enumerate(mesh.materials):
        mine = chosen[mesh.face_material[chosen] == index]
        if not len(mine):
            continue
        keep = kept_texels(material, labels)
        if keep is False:
            continue
        corners = mesh.vertices[mesh.faces[mine]]
        if keep is True or mesh.uvs is None:
            yield _whole(mine, corners)
            continue
        assert isinstance(keep, np.ndarray)
        yield from _cut(mine, corners, mesh.uvs[mesh.faces[mine]].astype(np.float64), keep)


def face_opaque_area(mesh: Mesh, labels: frozenset[int] | None = None) -> np.ndarray:
    """(M,) the opaque area of every face, m^2 (of texels of ``labels`` when given)."""
    out = np.zeros(len(mesh.faces))
    for pieces in opaque_pieces(mesh, labels):
        out += np.bincount(pieces.face, weights=pieces.area, minlength=len(mesh.faces))
    return out


def _whole(faces: np.ndarray, corners: np.ndarray) -> OpaquePieces:
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    vertices = np.zeros((len(faces), _MAX_VERTICES, 3))
    vertices[:, :3] = corners
    return OpaquePieces(faces, area, corners.mean(axis=1), vertices, np.full(len(faces), 3))


def _cut(faces: np.ndarray, corners: np.ndarray, uv_triangles: np.ndarray, mask: np.ndarray) -> Iterator[OpaquePieces]:
    """The pieces of triangles (3D ``corners``, UVs ``uv_triangles``) on texels ``mask`` keeps."""
    h, w = mask.shape
    tri = uv_triangles * np.array([w, h], np.float64)  # texel units: texel (r, c) is [c, c+1) x [r, r+1)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    area3 = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    lo = np.floor(tri.min(axis=1)).astype(np.int64)
    hi = np.floor(tri.max(axis=1)).astype(np.int64)  # the last texel touched, inclusive
    span = hi - lo + 1
    counts = span[:, 0] * span[:, 1]
    # no UV area to speak of (a sliver, collinear UVs): one texel decides for the triangle
    flat = np.abs(det) <= 1e-9 * np.maximum(counts, 1)
    if flat.any():
        first = np.floor(tri[flat, 0]).astype(np.int64)
        whole = mask[first[:, 1] % h, first[:, 0] % w]
        idx = np.flatnonzero(flat)[whole]
        yield _whole(faces[idx], corners[idx])
    todo = np.flatnonzero(~flat)
    ends = np.cumsum(counts[todo])
    start = 0
    while start < len(todo):
        before = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, before + CHUNK, side="right")), start + 1)
        sel = todo[start:stop]
        owner = np.repeat(sel, counts[sel])
        k = np.arange(len(owner)) - np.repeat(np.cumsum(counts[sel]) - counts[sel], counts[sel])
        col = lo[owner, 0] + k % span[owner, 0]
        row = lo[owner, 1] + k // span[owner, 0]
        keep = mask[row % h, col % w]
        x0, y0 = col.astype(np.float64), row.astype(np.float64)
        full, apart = _square_against(tri[owner], x0, y0, np.sign(det[owner]))
        # a triangle that touches no cut-away texel is one piece, as it is
        blocked = np.zeros(len(tri), bool)
        blocked[owner[~keep & ~apart]] = True
        whole = sel[~blocked[sel]]
        if len(whole):
            yield _whole(faces[whole], corners[whole])
        pick = keep & ~apart & blocked[owner]
        owner, x0, y0, full = owner[pick], x0[pick], y0[pick], full[pick]
        apart = np.zeros(len(owner), bool)
        # a texel wholly inside its triangle is a piece as it is; only the edges' texels are clipped
        poly = np.zeros((len(owner), _MAX_VERTICES + 1, 2))
        n = np.full(len(owner), 4)
        poly[full, :4, 0] = x0[full, None] + _SQUARE[:, 0]
        poly[full, :4, 1] = y0[full, None] + _SQUARE[:, 1]
        n[apart] = 0
        cut = ~full & ~apart
        if cut.any():
            poly[cut], n[cut] = _clipped(tri[owner[cut]], x0[cut], y0[cut])
        uv_area, uv_centre = _shoelace(poly, n)
        live = uv_area > 0.0
        owner, poly, n, uv_area, uv_centre = owner[live], poly[live], n[live], uv_area[live], uv_centre[live]
        # UV -> 3D: each triangle's affine map, through barycentric coordinates (s, t)
        inv = np.stack([np.stack([e2[owner, 1], -e2[owner, 0]], -1), np.stack([-e1[owner, 1], e1[owner, 0]], -1)], 1)
        inv /= det[owner, None, None]
        origin, a, b = corners[owner, 0], corners[owner, 1] - corners[owner, 0], corners[owner, 2] - corners[owner, 0]
        st = _inside(np.einsum("kij,kvj->kvi", inv, poly[:, :_MAX_VERTICES] - tri[owner, 0][:, None]))
        vertices = origin[:, None] + st[..., :1] * a[:, None] + st[..., 1:] * b[:, None]
        st = _inside(np.einsum("kij,kj->ki", inv, uv_centre - tri[owner, 0]))
        centroid = origin + st[:, :1] * a + st[:, 1:] * b
        area = uv_area * area3[owner] / (0.5 * np.abs(det[owner]))
        yield OpaquePieces(faces[owner], area, centroid, vertices, n)
        start = stop


#: a unit texel's corners, counter-clockwise
_SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _square_against(
    tri: np.ndarray, x0: np.ndarray, y0: np.ndarray, orientation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(K,) does each triangle (K x 3 x 2, ``orientation`` the sign of its area) hold all of its
    unit square [x0, x0+1] x [y0, y0+1], and (K,) does one of its edges leave the whole square
    outside (then they share nothing)?"""
    inside = np.ones(len(tri), bool)
    apart = np.zeros(len(tri), bool)
    for i in range(3):
        a, b = tri[:, i], tri[:, (i + 1) % 3]
        beyond = np.ones(len(tri), bool)
        for cx, cy in _SQUARE:
            side = orientation * ((b[:, 0] - a[:, 0]) * (y0 + cy - a[:, 1]) - (b[:, 1] - a[:, 1]) * (x0 + cx - a[:, 0]))
            inside &= side >= 0.0
            beyond &= side < 0.0
        apart |= beyond
    return inside, apart


def _inside(st: np.ndarray) -> np.ndarray:
    """Barycentric (s, t) held inside their triangle: a sliver's inverse map amplifies rounding,
    and every piece lies on its triangle."""
    st = np.clip(st, 0.0, 1.0)
    over = st.sum(axis=-1, keepdims=True)
    return np.where(over > 1.0, st / np.maximum(over, 1e-300), st)


def _clipped(tri: np.ndarray, x0: np.ndarray, y0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle (K x 3 x 2) clipped to its unit square [x0, x0+1] x [y0, y0+1]: the
    polygons (K x 8 x 2) and their corner counts."""
    poly = np.zeros((len(tri), _MAX_VERTICES + 1, 2))
    poly[:, :3] = tri
    n = np.full(len(tri), 3)
    for axis, bound, sign in ((0, x0, -1.0), (0, x0 + 1.0, 1.0), (1, y0, -1.0), (1, y0 + 1.0, 1.0)):
        poly, n = _clip(poly, n, axis, bound, sign)
    return poly, n


def _next(poly: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Each polygon's corners shifted by one (corner i -> corner i+1, the last -> the first)."""
    v = poly.shape[1]
    following = (np.arange(v)[None, :] + 1) % np.maximum(n, 1)[:, None]
    return np.take_along_axis(poly, following[..., None], axis=1)


def _shoelace(poly: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K,) the area and (K x 2) the centre of area of each polygon's first ``n`` corners."""
    b = _next(poly, n)
    live = np.arange(poly.shape[1])[None, :] < n[:, None]
    cross = np.where(live, poly[..., 0] * b[..., 1] - poly[..., 1] * b[..., 0], 0.0)
    twice = cross.sum(axis=1)
    moment = ((poly + b) * cross[..., None]).sum(axis=1)
    safe = np.where(twice == 0.0, 1.0, twice)
    return 0.5 * np.abs(twice), moment / (3.0 * safe[:, None])


def _clip(poly: np.ndarray, n: np.ndarray, axis: int, bound: np.ndarray, sign: float) -> tuple[np.ndarray, np.ndarray]:
    """Each polygon (K x V x 2, its first ``n`` corners) clipped to the half-plane
    sign * (p[axis] - bound) <= 0 (Sutherland-Hodgman: a convex polygon stays convex). Each
    corner gives up to two (itself when inside, the edge's crossing when it crosses), compacted
    in order."""
    k, v = poly.shape[:2]
    b = _next(poly, n)
    da = sign * (poly[..., axis] - bound[:, None])
    db = sign * (b[..., axis] - bound[:, None])
    live = np.arange(v)[None, :] < n[:, None]
    a_in = da <= 0.0
    cross = live & (a_in != (db <= 0.0))
    t = np.where(cross, da / np.where(cross, da - db, 1.0), 0.0)
    crossing = poly + t[..., None] * (b - poly)
    slots = np.stack([poly, crossing], axis=2).reshape(k, 2 * v, 2)
    valid = np.stack([live & a_in, cross], axis=2).reshape(k, 2 * v)
    order = np.argsort(~valid, axis=1, kind="stable")[:, :v]
    return np.take_along_axis(slots, order[..., None], axis=1), valid.sum(axis=1)
