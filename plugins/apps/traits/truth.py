"""A plant's traits, exact from its model: what a phenotyping study reports of a plant (leaf
count and area, leaf angles, height, canopy size), computed from the mesh and the opacity of its
textures, leaf by leaf.

A leaf is a leaf instance (the mesh's ``face_instance``: the id the instance masks, the COCO
export and ``traits.json`` share); its surface is the opaque part of its triangles (a cut-out
card counts its leaf, not its rectangle: :mod:`agrisim.plugins.apps.traits.opaque_area`). Lengths in metres,
areas in square metres, angles in degrees, positions in the plant's frame (z up from the soil;
the stem at x = y = 0).

- **Inclination** of a surface: the angle between its normal and the vertical, 0 for a flat
  leaf, 90 for an upright one (one-sided: a leaf seen from below has the same); a leaf's is the
  area-weighted mean over its surface, with the area-weighted shares in 10-degree bins.
- **Azimuth**: the compass direction its upward normal leans to, counter-clockwise from +x,
  the area-weighted circular mean (each piece weighted by how far it leans).
- **Length along the midrib**: the leaf's opaque surface cut into slices across its long axis
  (the first principal axis of its area); the midrib is the line through the slices' middles
  (halfway across each one's outline), smoothed by a cubic, from the leaf's one end to the
  other; its length is that line's. **Width**: the widest slice, across the midrib (the second
  principal axis). The **attachment** is the midrib's end
  nearer the stem (x = y = 0).
- **Plant**: height is the top of its opaque surface (every organ); crown diameter the widest
  horizontal span of it; convex-hull volume that of all of it; projected area from above that of
  its shadow under the sun at the zenith (rasterised at :data:`PROJECTION_CELL_M`).
- **Leaf angle distribution** (all leaves' inclinations, area weighted) against de Wit's six
  classes (planophile, erectophile, plagiophile, extremophile, uniform, spherical; Goel &
  Strebel 1984's densities): the class nearest in total variation of the 10-degree shares.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.plugins.apps.traits.opaque_area import OpaquePieces, opaque_pieces
from agrisim.scene.model import Plant

#: edges of the inclination histograms, degrees
INCLINATION_BINS = np.arange(0.0, 91.0, 10.0)
#: side of the cells the projected area is rasterised on, m
PROJECTION_CELL_M = 2.5e-4
#: triangles cut at once (the progress reported after each batch)
FACE_BATCH = 4096
#: slices across a leaf's long axis that its midrib and width are measured on
SLICES = 48


@dataclass
class LeafTraits:
    """One leaf's traits (see the module's definitions)."""

    id: int
    area_m2: float
    length_m: float
    width_m: float
    inclination_deg: float
    azimuth_deg: float
    inclination_shares: list[float]
    attachment_m: list[float]
    centroid_m: list[float]


@dataclass
class PlantTraits:
    """A plant's traits and its leaves' (see the module's definitions)."""

    leaf_count: int
    leaf_area_m2: float
    height_m: float
    crown_diameter_m: float
    convex_hull_volume_m3: float
    projected_area_m2: float
    mean_inclination_deg: float
    inclination_shares: list[float]
    de_wit_class: str
    de_wit_distance: dict[str, float]
    leaves: list[LeafTraits] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


# -------------------------------------------------------------------------- de Wit's classes


def _cumulative(kind: str, theta: np.ndarray) -> np.ndarray:
    """The share of leaf area below inclination ``theta`` (radians) under de Wit's ``kind``."""
    two_over_pi = 2.0 / np.pi
    if kind == "spherical":
        return 1.0 - np.cos(theta)
    if kind == "uniform":
        return two_over_pi * theta
    c, k = {"planophile": (1, 2), "erectophile": (-1, 2), "plagiophile": (-1, 4), "extremophile": (1, 4)}[kind]
    return two_over_pi * (theta + c * np.sin(k * theta) / k)


DE_WIT = ("planophile", "erectophile", "plagiophile", "extremophile", "uniform", "spherical")


def de_wit_shares(kind: str) -> np.ndarray:
    """The leaf-area shares of de Wit's ``kind`` in the bins :data:`INCLINATION_BINS`."""
    return np.diff(_cumulative(kind, np.radians(INCLINATION_BINS)))


def nearest_de_wit(shares: np.ndarray) -> tuple[str, dict[str, float]]:
    """The de Wit class nearest ``shares`` (total variation distance, 0 to 1), and every class's."""
    distance = {k: float(0.5 * np.abs(np.asarray(shares) - de_wit_shares(k)).sum()) for k in DE_WIT}
    return min(distance, key=distance.__getitem__), distance


# -------------------------------------------------------------------------- the traits


def _histogram(theta_deg: np.ndarray, weights: np.ndarray) -> np.ndarray:
    counts, _ = np.histogram(np.clip(theta_deg, 0.0, 90.0), INCLINATION_BINS, weights=weights)
    total = counts.sum()
    return counts / total if total > 0 else counts


class _Reducer:
    """What the plant's traits need of its opaque pieces, gathered chunk by chunk: per face area
    and moment, the leaves' pieces, the convex hull's candidates, the shadow from above."""

    def __init__(self, plant: Plant) -> None:
        mesh = plant.mesh
        m = len(mesh.faces)
        self.instance = np.zeros(m, np.int64) if mesh.face_instance is None else mesh.face_instance.astype(np.int64)
        self.area = np.zeros(m)
        self.moment = np.zeros((m, 3))
        self.leaf_parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (instance, centroid, area)
        self.leaf_corners: list[tuple[np.ndarray, np.ndarray]] = []  # (instance, corner): where leaves end
        self.hull_points = np.zeros((0, 3))
        lo, hi = mesh.vertices[:, :2].min(axis=0), mesh.vertices[:, :2].max(axis=0)
        self.origin = lo - 2 * PROJECTION_CELL_M
        cells = np.ceil((hi - self.origin) / PROJECTION_CELL_M).astype(int) + 2
        self.shadow = np.zeros((int(cells[1]), int(cells[0])), np.uint8)

    def add(self, pieces: OpaquePieces) -> None:
        from scipy.spatial import ConvexHull

        m = len(self.area)
        self.area += np.bincount(pieces.face, weights=pieces.area, minlength=m)
        for axis in range(3):
            self.moment[:, axis] += np.bincount(
                pieces.face, weights=pieces.area * pieces.centroid[:, axis], minlength=m
            )
        inst = self.instance[pieces.face]
        leaf = inst > 0
        if leaf.any():
            self.leaf_parts.append((inst[leaf], pieces.centroid[leaf].astype(np.float32), pieces.area[leaf]))
            live = np.arange(pieces.vertices.shape[1])[None, :] < pieces.count[leaf][:, None]
            owner = np.broadcast_to(inst[leaf][:, None], live.shape)[live]
            self.leaf_corners.append((owner, pieces.vertices[leaf][live].astype(np.float32)))
        corners = np.concatenate([self.hull_points, pieces.corners()])
        if len(corners) >= 4:
            try:
                self.hull_points = corners[ConvexHull(corners).vertices]
            except Exception:  # a flat plant (one card): qhull refuses, every corner stays a candidate
                self.hull_points = corners
        else:
            self.hull_points = corners
        self._cast_shadow(pieces)

    def _cast_shadow(self, pieces: OpaquePieces) -> None:
        import cv2

        shift = 8  # subpixel bits of cv2.fillPoly
        xy = (pieces.vertices[..., :2] - self.origin) / PROJECTION_CELL_M
        fixed = np.round(xy * (1 << shift)).astype(np.int32)
        for n in np.unique(pieces.count):
            sel = pieces.count == n
            cv2.fillPoly(self.shadow, list(fixed[sel, :n]), 1, lineType=cv2.LINE_8, shift=shift)


def plant_traits(plant: Plant, progress: Callable[[int, int], None] | None = None) -> PlantTraits:
    """Every trait of ``plant`` and of each of its leaves, exact from its mesh (see the module);
    ``progress(done, total)`` hears of the triangles cut. A plant without leaf instances is
    refused with a UserError (nothing to measure leaf by leaf)."""
    mesh = plant.mesh
    if mesh.face_instance is None or not np.any(mesh.face_instance > 0):
        raise UserError(
            f"plant {plant.name!r} has no leaves: its mesh has no leaf instances "
            "(a glTF plant names them in extras.agrisim.face_instance)"
        )
    reduce = _Reducer(plant)
    total = len(mesh.faces)
    for start in range(0, total, FACE_BATCH):
        for pieces in opaque_pieces(mesh, faces=np.arange(start, min(start + FACE_BATCH, total))):
            reduce.add(pieces)
        if progress is not None:
            progress(min(start + FACE_BATCH, total), total)
    normals = np.cross(
        mesh.vertices[mesh.faces[:, 1]] - mesh.vertices[mesh.faces[:, 0]],
        mesh.vertices[mesh.faces[:, 2]] - mesh.vertices[mesh.faces[:, 0]],
    )
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    normals *= np.where(normals[:, 2:3] < 0.0, -1.0, 1.0)  # one-sided: the upward normal
    theta = np.degrees(np.arccos(np.clip(normals[:, 2], -1.0, 1.0)))
    leaves = _leaves(reduce, normals, theta)
    on_leaf = reduce.instance > 0
    shares = _histogram(theta[on_leaf], reduce.area[on_leaf])
    kind, distance = nearest_de_wit(shares)
    hull = reduce.hull_points
    top = float(hull[:, 2].max()) if len(hull) else 0.0
    volume, diameter = hull_figures(hull)
    leaf_area = float(sum(leaf.area_m2 for leaf in leaves))
    return PlantTraits(
        leaf_count=len(leaves),
        leaf_area_m2=leaf_area,
        height_m=top,
        crown_diameter_m=diameter,
        convex_hull_volume_m3=volume,
        projected_area_m2=float(reduce.shadow.sum()) * PROJECTION_CELL_M**2,
        mean_inclination_deg=float(np.average(theta[on_leaf], weights=reduce.area[on_leaf])) if leaf_area > 0 else 0.0,
        inclination_shares=shares.tolist(),
        de_wit_class=kind,
        de_wit_distance=distance,
        leaves=leaves,
    )


def hull_figures(points: np.ndarray) -> tuple[float, float]:
    """(volume, widest horizontal span) of the convex hull of ``points`` (N x 3), m^3 and m."""
    from scipy.spatial import ConvexHull

    if len(points) < 4:
        return 0.0, 0.0
    try:
        volume = float(ConvexHull(points).volume)
    except Exception:  # flat: no volume
        volume = 0.0
    xy = points[:, :2]
    try:
        xy = xy[ConvexHull(xy).vertices]
    except Exception:  # collinear: every point stays a candidate
        pass
    # the widest span is between two hull corners; rows in chunks keep the pairs' memory small
    span = 0.0
    for start in range(0, len(xy), 1024):
        rows = xy[start : start + 1024]
        span = max(span, float(np.sqrt(((rows[:, None, :] - xy[None, :, :]) ** 2).sum(-1)).max()))
    return volume, span


def _leaves(reduce: _Reducer, normals: np.ndarray, theta: np.ndarray) -> list[LeafTraits]:
    inst, area = reduce.instance, reduce.area
    ids = np.unique(inst[(inst > 0) & (area > 0)])
    if not len(ids):
        return []
    parts = reduce.leaf_parts
    p_inst = np.concatenate([p[0] for p in parts])
    p_xyz = np.concatenate([p[1] for p in parts]).astype(np.float64)
    p_area = np.concatenate([p[2] for p in parts])
    order = np.argsort(p_inst, kind="stable")
    p_inst, p_xyz, p_area = p_inst[order], p_xyz[order], p_area[order]
    bounds = np.searchsorted(p_inst, np.concatenate([ids, [ids[-1] + 1]]))
    c_inst = np.concatenate([c[0] for c in reduce.leaf_corners])
    c_xyz = np.concatenate([c[1] for c in reduce.leaf_corners]).astype(np.float64)
    order = np.argsort(c_inst, kind="stable")
    c_inst, c_xyz = c_inst[order], c_xyz[order]
    c_bounds = np.searchsorted(c_inst, np.concatenate([ids, [ids[-1] + 1]]))
    faces_of = np.argsort(inst, kind="stable")
    f_bounds = np.searchsorted(inst[faces_of], np.concatenate([ids, [ids[-1] + 1]]))
    out = []
    for i, leaf_id in enumerate(ids):
        faces = faces_of[f_bounds[i] : f_bounds[i + 1]]
        a = area[faces]
        total = float(a.sum())
        centroid = (reduce.moment[faces].sum(axis=0) / total).tolist()
        n = normals[faces]
        lean = (a[:, None] * n[:, :2]).sum(axis=0)
        azimuth = float(np.degrees(np.arctan2(lean[1], lean[0])) % 360.0)
        length, width, attachment = _midrib(
            p_xyz[bounds[i] : bounds[i + 1]], p_area[bounds[i] : bounds[i + 1]], c_xyz[c_bounds[i] : c_bounds[i + 1]]
        )
        out.append(
            LeafTraits(
                id=int(leaf_id),
                area_m2=total,
                length_m=length,
                width_m=width,
                inclination_deg=float(np.average(theta[faces], weights=a)),
                azimuth_deg=azimuth,
                inclination_shares=_histogram(theta[faces], a).tolist(),
                attachment_m=attachment,
                centroid_m=centroid,
            )
        )
    return out


def _midrib(points: np.ndarray, weights: np.ndarray, corners: np.ndarray) -> tuple[float, float, list[float]]:
    """(length along the midrib, widest slice, attachment point) of a leaf's opaque surface,
    given as its pieces' centres and areas (where its area lies) and corners (where it ends;
    see the module)."""
    if not len(points) or len(corners) < 3:
        p = points.mean(axis=0) if len(points) else np.zeros(3)
        return 0.0, 0.0, p.tolist()
    w = weights / weights.sum()
    mean = w @ points
    # the axes of its area; of its outline where too few pieces make it (a card of two triangles)
    outline = np.unique(corners, axis=0)
    spread = (points - mean) * np.sqrt(w)[:, None] if len(points) >= 3 else outline - outline.mean(axis=0)
    _, _, vt = np.linalg.svd(spread, full_matrices=False)
    c_along, c_across = (corners - mean) @ vt[0], (corners - mean) @ vt[1]
    lo, hi = float(c_along.min()), float(c_along.max())
    edges = np.linspace(lo, hi, SLICES + 1)

    def slot_of(x: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, SLICES - 1)

    # each slice's middle: halfway across its outline, its outline's mean height off the plane;
    # the midrib is their line smoothed by a cubic in the long axis (a texel's jitter from slice
    # to slice would lengthen a straight one), from end to end
    c_slot = slot_of(c_along)
    c_off = (corners - mean) @ vt[2]
    top = np.full(SLICES, -np.inf)
    bottom = np.full(SLICES, np.inf)
    np.maximum.at(top, c_slot, c_across)
    np.minimum.at(bottom, c_slot, c_across)
    hits = np.bincount(c_slot, minlength=SLICES)
    width = float(np.max(np.where(hits > 0, top - bottom, 0.0)))
    filled = (hits > 0) & (top > bottom)  # (a slice of one corner has no middle)
    u = (edges[:-1] + edges[1:])[filled] / 2
    middle = [
        (top[filled] + bottom[filled]) / 2,
        np.bincount(c_slot, weights=c_off, minlength=SLICES)[filled] / hits[filled],
    ]
    degree = min(3, int(filled.sum()) - 1)
    if degree < 1:
        curve = np.array([[lo, 0.0, 0.0], [hi, 0.0, 0.0]])
    else:
        fits = [np.polynomial.Polynomial.fit(u, m, degree) for m in middle]
        t = np.linspace(lo, hi, 257)
        curve = np.stack([t, fits[0](t), fits[1](t)], 1)
    length = float(np.linalg.norm(np.diff(curve, axis=0), axis=1).sum())
    ends = mean + curve[[0, -1]] @ vt
    base = min(ends, key=lambda p: (float(np.hypot(p[0], p[1])), float(p[2])))
    return length, width, base.tolist()
