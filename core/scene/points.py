"""Plants as point clouds: a mesh plant's visible surface sampled into labelled, coloured
points (``--as-points``, the paper's cleaned Coltsfoot made reproducible), and the point size a
cloud gets when none is chosen.

Sampling is uniform by area over the opaque texels only (what a camera can see of a leaf card,
as the ground truth of :mod:`agrisim.evaluation.metrics` is): each point takes the albedo of its
texel (nearest, times the material's colour factor, in linear light), the label of its label
texel and the leaf instance of its triangle. A card's two sides share their points; each is
drawn as a sphere, which shows on both sides.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from agrisim.errors import UserError
from agrisim.scene.colour import linear_to_srgb, srgb_to_linear
from agrisim.scene.model import Mesh, Plant, PointSet
from agrisim.scene.texturing import (
    interpolate,
    interpolate_uv,
    labels_at_samples,
    opaque_samples,
    sample_nearest,
    sample_surface,
)

#: Most points a plant may have. A traced point costs about 200 bytes (its sphere in the
#: tracer, its bounding box in the hierarchy, its colour, label and instance), so this bounds a
#: run's point plant near 1 GB; a million points already cover a 40 cm plant at 0.3 mm spacing,
#: finer than a 1080p view resolves.
MAX_POINTS = 5_000_000

#: The default point size covers the surface: the distance to a point's 8th nearest neighbour
#: measures the local density (8 points per pi d^2 of surface), and spheres of radius
#: sqrt(ln(100) / (pi density)) leave 1% of a randomly sampled surface uncovered (the share a
#: Poisson process of discs misses is exp(-density pi r^2)); on a regular grid of spacing s that
#: is a diameter of 2.1 s (the paper's cleaned scan, 1 mm apart, looked whole at 2 mm).
NEIGHBOURS = 8
UNCOVERED = 0.01


def check_count(count: int, what: str = "--as-points") -> None:
    """Refuse a point count below 1 or above :data:`MAX_POINTS` (one line, saying why)."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise UserError(f"{what} must be a whole number of points >= 1, got {count!r}")
    if count > MAX_POINTS:
        raise UserError(
            f"{what} {count:,} is too many: at most {MAX_POINTS:,} points (each costs about 200 bytes while "
            "traced; 1,000,000 already cover a plant at 0.3 mm spacing, finer than a 1080p view resolves)"
        )


def check_size(size: float, what: str = "--point-size") -> None:
    """Refuse a point size that is not a finite number > 0 (metres)."""
    if isinstance(size, bool) or not isinstance(size, (int, float)) or not math.isfinite(size) or size <= 0:
        raise UserError(f"{what} must be a finite number of metres > 0 (the diameter of each point), got {size!r}")
    if size > 0.5:
        raise UserError(
            f"{what} {size:g} m is larger than a plant; it is the diameter of each point, in metres (0.002 is 2 mm)"
        )


def albedo_at_samples(mesh: Mesh, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """sRGB colour (K x 3 uint8) of surface samples: the albedo texel nearest each (or white
    without a texture) times the material's colour factor and the vertex colour there,
    multiplied in linear light."""
    out = np.zeros((len(faces), 3), np.uint8)
    uv = interpolate_uv(mesh, faces, bary) if mesh.uvs is not None else np.zeros((len(faces), 2))
    tint = np.ones((len(faces), 3))
    if mesh.colors is not None:
        tint = interpolate(mesh, mesh.colors.astype(np.float64), faces, bary)
    mats = mesh.face_material[faces]
    for i in np.unique(mats):
        sel = np.flatnonzero(mats == i)
        mat = mesh.materials[i]
        if mat.albedo is not None:
            linear = srgb_to_linear(sample_nearest(mat.albedo, uv[sel])[:, :3] / 255.0)
        else:
            linear = np.ones((len(sel), 3))
        linear = linear * np.asarray(mat.color[:3], np.float64) * tint[sel]
        out[sel] = np.round(linear_to_srgb(np.clip(linear, 0.0, 1.0)) * 255.0).astype(np.uint8)
    return out


def sample_points(mesh: Mesh, count: int, seed: int = 0) -> PointSet:
    """``count`` points on the opaque surface of ``mesh``, uniform by area, with colours,
    labels and leaf instances (module doc). Deterministic for a seed."""
    check_count(count)
    if len(mesh.faces) == 0 or not np.any(mesh.areas > 0):
        raise UserError(f"plant {mesh.name!r} has no surface to sample points on")
    rng = np.random.default_rng(seed)
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    have, opaque_share = 0, 1.0
    for _ in range(64):  # rejection of cut-out texels, in rounds sized by the share kept so far
        want = count - have
        draw = min(int(want / max(opaque_share, 0.01) * 1.1) + 256, 4 * MAX_POINTS)
        points, faces, bary = sample_surface(mesh, draw, rng)
        keep = np.flatnonzero(opaque_samples(mesh, faces, bary))
        opaque_share = max(len(keep) / draw, 1e-4)
        keep = keep[:want]
        parts.append((points[keep], faces[keep], bary[keep]))
        have += len(keep)
        if have >= count:
            break
    else:
        raise UserError(f"plant {mesh.name!r}: opacity cuts away nearly all of its surface; no points to sample")
    points = np.concatenate([p for p, _, _ in parts])
    faces = np.concatenate([f for _, f, _ in parts])
    bary = np.concatenate([b for _, _, b in parts])
    labels = labels_at_samples(mesh, faces, bary)
    instances = None
    if mesh.face_instance is not None:
        instances = np.where(labels > 0, mesh.face_instance[faces], 0).astype(np.uint16)
    return PointSet(points, albedo_at_samples(mesh, faces, bary), labels, instances)


def neighbour_distance(positions: np.ndarray, k: int = NEIGHBOURS, probes: int = 100_000, seed: int = 0) -> float:
    """Median distance from a point to its ``k``-th nearest other point (over up to ``probes``
    points; 0 when there are not more than ``k`` points)."""
    from scipy.spatial import cKDTree

    if len(positions) <= k:
        return 0.0
    tree = cKDTree(positions)
    rng = np.random.default_rng(seed)
    probe = positions if len(positions) <= probes else positions[rng.choice(len(positions), probes, replace=False)]
    d, _ = tree.query(probe, k=k + 1)
    return float(np.median(d[:, k]))


def default_size(positions: np.ndarray) -> float:
    """The point diameter a cloud gets when none is chosen: one that covers its surface (see
    :data:`NEIGHBOURS`); 1 mm for clouds of a few points."""
    d = neighbour_distance(positions)
    if d <= 0:
        return 1e-3
    return 2.0 * d * math.sqrt(math.log(1.0 / UNCOVERED) / NEIGHBOURS)


def as_points(plant: Plant, count: int | None, size: float | None, seed: int = 0) -> Plant:
    """``plant`` drawn as points: its own (a scan) or ``count`` sampled on its surface, of
    diameter ``size`` (default: :func:`default_size`). A plant of points with ``count`` is
    refused; without either, a mesh plant comes back as it is."""
    if size is not None:
        check_size(size)
    if count is not None:
        check_count(count)
        if plant.points is not None:
            raise UserError(f"--as-points: plant {plant.name!r} is already a point cloud; it applies to mesh plants")
        points = sample_points(plant.mesh, count, seed)
        note = f"drawn as {count:,} points sampled on its opaque surface (seed {seed})"
    elif plant.points is not None:
        points, note = plant.points, f"a point cloud of {len(plant.points):,} points"
    else:
        if size is not None:
            raise UserError("--point-size applies to point plants: a point-cloud file, or --as-points N")
        return plant
    if size is None:
        size = points.size if points.size is not None else default_size(points.positions)
        why = "" if points.size is not None else " (enough to cover its surface; --point-size sets it)"
    else:
        why = ""
    points = dataclasses.replace(points, size=float(size))
    notes = [*plant.notes, f"{note}, each a sphere {size * 1e3:.4g} mm across{why}"]
    return dataclasses.replace(plant, points=points, notes=notes)
