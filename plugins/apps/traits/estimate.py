"""What a phenotyping pipeline measures of a plant from a run's views, with Open3D and the
field's usual steps; each estimate meets its truth (:mod:`agrisim.plugins.apps.traits.truth`) by leaf id.

1. **Fusion** (:func:`fuse_views`): each view's plant pixels (labels > 0) with a depth within
   ``max_depth`` are back-projected through the run's camera, lens included, and moved to the
   plant's frame (z up from the soil, the stem at x = y = 0: the rig knows where its pot is) by
   the view's pose; on a sensor's depth a voxel of the ``voxel_m`` grid counts where at least
   :data:`MIN_VIEWS` views put a point in it; the points are merged on it (each voxel's mean point), once for
   the whole plant and once per leaf instance (the id the instance masks carry).
   ``depth`` is the run's exact depth (``truth``) or its depth sensor's (``sensor``; the exact
   one where the run had none). The masks are the renderer's, exact, whatever the depth.
2. **Leaves** (:func:`leaf_estimates`): area from a surface fitted to a leaf's points,
   inclination and azimuth from their normals.
3. **The plant** (:func:`measure`): height, convex hull and crown from the plant's points once
   Open3D's statistical outlier removal has dropped what floats free of the plant (a sensor's
   flying pixels); leaf count and area from the leaves seen; and what an instance-free pipeline
   would count: the leaves' points, ids dropped, clustered by Open3D's DBSCAN
   (:func:`cluster_leaves`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.evaluation.views import backproject, load_view
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json, capture_order, read_run

#: voxel of the merged clouds, m (the paper's 1 mm)
VOXEL_M = 1e-3
#: depth beyond which pixels are dropped, m (the paper's 1 m)
MAX_DEPTH_M = 1.0
#: fewest views that must put a point in a voxel for it to count: a surface is seen from many
#: views, a depth sensor's error (a leaf's pixel given the depth behind it) lands elsewhere in
#: each (COLMAP's fusion likewise asks for several pixels); 3 costs an exact run about 1% of
#: leaf area (coltsfoot: MAPE 1.6% -> 2.7%, amaryllis 5.3% -> 7.4%: the outline is seen by
#: fewer views) and takes a D435's inclination error from 17 to 3 degrees, so it applies to a
#: sensor's depth only, as a pipeline filters as its camera needs
MIN_VIEWS = 3
#: fewest fused points a leaf (or a cluster) needs to count as seen: fewer is a glimpse of an
#: edge, no surface to measure
MIN_LEAF_POINTS = 10
#: DBSCAN's neighbourhood, in voxels: points of one leaf lie a voxel or so apart, so 2.5 bridges
#: the grid's diagonals and a missed voxel, not the gap between two leaves that do not touch
CLUSTER_EPS_VOXELS = 2.5
#: a cluster is one leaf when this share of its points comes from one leaf ...
CLUSTER_PURITY = 0.9
#: ... and holds at least this share of that leaf's points
CLUSTER_COVER = 0.5


@dataclass
class FusedPlant:
    """A run's plant as its views saw it (see :func:`fuse_views`), in the plant's frame."""

    plant: np.ndarray
    leaves: dict[int, np.ndarray]
    views: int
    depth: str


def measurable_frames(run_dir: Path, run: dict[str, Any] | None = None) -> list[str]:
    """The complete run's frames in capture order; a UserError where it has none with instance
    masks, which per-leaf estimates need."""
    run = read_run(Path(run_dir))[0] if run is None else run
    frames = capture_order(run, sorted(run.get("frames_complete") or []))
    if not frames or not layout.image(Path(run_dir), "instances", frames[0]).is_file():
        raise UserError(
            f"the run in {run_dir} has no instance masks (instances/): per-leaf estimates need them "
            "(a plant whose leaves are instances, rendered by raycast or mitsuba)"
        )
    return frames


def plant_T_world(run: dict[str, Any]) -> np.ndarray:
    """The plant's frame (the soil at the pot's centre, z up) from the world, by the cell of
    ``run`` (its run.json)."""
    from agrisim.config import build_config
    from agrisim.robot.cell import soil_pose
    from agrisim.validation import open_rig

    return np.linalg.inv(soil_pose(open_rig(build_config(run["config"]))[1]))


def fuse_views(
    run_dir: Path,
    depth: str = "truth",
    voxel_m: float = VOXEL_M,
    max_depth_m: float = MAX_DEPTH_M,
    progress: Callable[[int, int], None] | None = None,
    min_views: int | None = None,
) -> FusedPlant:
    """The plant's and each leaf's fused points (N x 3, the plant's frame) from the complete run
    in ``run_dir``; ``progress(done, total)`` hears of the views read. ``min_views``: the views a
    voxel needs (default: 1 on exact depth, :data:`MIN_VIEWS` on a sensor's). A run without
    instance masks is refused with a UserError."""
    run_dir = Path(run_dir)
    run, cameras = read_run(run_dir)
    frames = measurable_frames(run_dir, run)
    camera = camera_from_json(cameras["intrinsics"])
    plant_from_world = plant_T_world(run)
    sensor = (run.get("backends") or {}).get("sensor", "exact")
    source = "truth" if depth == "truth" or sensor == "exact" else f"sensor:{sensor}"
    if min_views is None:
        min_views = 1 if source == "truth" else MIN_VIEWS
    ids: list[np.ndarray] = []
    points: list[np.ndarray] = []
    seen_by: list[np.ndarray] = []
    for i, frame in enumerate(frames):
        world_T_camera = np.asarray(cameras["frames"][frame]["world_T_camera"], np.float64)
        view = load_view(run_dir, frame, camera, plant_from_world @ world_T_camera, depth)
        instances = view.images.instances
        assert instances is not None
        plant = view.images.labels > 0
        p, _ = backproject(view, plant, max_depth_m)
        if len(p):
            # backproject keeps the mask's pixels in row-major order where the depth is kept
            v, u = np.nonzero(plant & (view.images.depth > 0))
            near = view.images.depth[v, u] <= np.float32(max_depth_m)
            ids.append(instances[v[near], u[near]].astype(np.int64))
            points.append(p)
            seen_by.append(np.full(len(p), i, np.int64))
        if progress is not None:
            progress(i + 1, len(frames))
    if not points:
        return FusedPlant(np.zeros((0, 3)), {}, len(frames), source)
    every_id, every_point = np.concatenate(ids), np.concatenate(points)
    keep = _seen_by(np.floor(every_point / voxel_m).astype(np.int64), np.concatenate(seen_by)) >= min_views
    every_id, every_point = every_id[keep], every_point[keep]
    whole = _merged(np.zeros(len(every_point), np.int64), every_point, voxel_m)
    leafy = every_id > 0
    return FusedPlant(
        whole.get(0, np.zeros((0, 3))), _merged(every_id[leafy], every_point[leafy], voxel_m), len(frames), source
    )


def _seen_by(cells: np.ndarray, view: np.ndarray) -> np.ndarray:
    """For each point (its voxel ``cells`` and ``view``), how many views put a point in its voxel."""
    # one int64 a voxel (21 bits an axis: +-1 km of millimetres) and one a (voxel, view) pair,
    # as 1-D np.unique is many times faster than rows
    c = cells - cells.min(axis=0)
    key = (c[:, 0] << 42) | (c[:, 1] << 21) | c[:, 2]
    _, cell = np.unique(key, return_inverse=True)
    cell = cell.reshape(-1)
    pairs = np.unique(cell * (int(view.max()) + 1) + view)
    return np.bincount(pairs // (int(view.max()) + 1), minlength=int(cell.max()) + 1)[cell]


def _merged(ids: np.ndarray, points: np.ndarray, voxel_m: float) -> dict[int, np.ndarray]:
    """Points merged per id on a ``voxel_m`` grid: each occupied voxel's mean point."""
    if not len(points):
        return {}
    cells = np.floor(points / voxel_m).astype(np.int64)
    keys = np.column_stack([ids, cells])
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.stack([np.bincount(inverse, weights=points[:, k]) for k in range(3)], 1)
    means = sums / counts[:, None]
    owner = np.zeros(len(counts), np.int64)
    owner[inverse] = ids
    return {int(leaf): means[owner == leaf] for leaf in np.unique(owner)}


@dataclass
class LeafEstimate:
    """One leaf as measured from its fused points (see :func:`leaf_estimates`)."""

    id: int
    points: int
    area_m2: float
    inclination_deg: float
    azimuth_deg: float


def leaf_estimates(clouds: dict[int, np.ndarray], voxel_m: float = VOXEL_M) -> list[LeafEstimate]:
    """Each leaf's area, inclination and azimuth from its fused points (:func:`fuse_views`).

    - Area: the surface Open3D's ball pivoting (Bernardini et al. 1999) lays on the points, with
      balls of 1.5 and 3 times their mean spacing (at least a voxel): it follows one sheet of
      points as a leaf is one sheet, where a Poisson surface closes it into a shell (twice the
      area) and a 3D alpha shape thickens it. Holes the views left stay holes: an unseen part
      of a leaf is not counted.
    - Inclination and azimuth: each point's normal from its neighbours within 3 spacings (PCA,
      Open3D), turned upward, averaged as :mod:`agrisim.plugins.apps.traits.truth` averages the surface's.
    """
    import open3d as o3d

    out = []
    for leaf, points in sorted(clouds.items()):
        area, incline, azimuth = 0.0, 0.0, 0.0
        if len(points) >= 3:
            cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
            # the balls and the normals' neighbourhoods scale with how densely the views sampled
            # the leaf: its points' mean spacing, never below the voxel
            spacing = max(voxel_m, float(np.mean(np.asarray(cloud.compute_nearest_neighbor_distance()))))
            cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=3 * spacing, max_nn=30))
            normals = np.asarray(cloud.normals)
            normals = normals * np.where(normals[:, 2:3] < 0.0, -1.0, 1.0)
            incline = float(np.degrees(np.arccos(np.clip(normals[:, 2], -1.0, 1.0))).mean())
            lean = normals[:, :2].sum(axis=0)
            azimuth = float(np.degrees(np.arctan2(lean[1], lean[0])) % 360.0)
            radii = o3d.utility.DoubleVector([1.5 * spacing, 3.0 * spacing])
            area = float(
                o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(cloud, radii).get_surface_area()
            )
        out.append(LeafEstimate(leaf, len(points), area, incline, azimuth))
    return out


@dataclass
class LeafClusters:
    """Leaves as an instance-free pipeline finds them (see :func:`cluster_leaves`)."""

    count: int
    one_leaf: int
    merged: int


def cluster_leaves(leaves: dict[int, np.ndarray], voxel_m: float = VOXEL_M) -> LeafClusters:
    """The leaves' fused points with their ids dropped, clustered by Open3D's DBSCAN
    (:data:`CLUSTER_EPS_VOXELS`), as a pipeline with a leaf mask and no instances would count
    leaves: ``count`` clusters of at least :data:`MIN_LEAF_POINTS` points; scored by the ids
    the pipeline did not use, ``one_leaf`` of them are one leaf (:data:`CLUSTER_PURITY` of their
    points from it, holding :data:`CLUSTER_COVER` of its points) and ``merged`` mix leaves that
    touch (no leaf reaches the purity)."""
    import open3d as o3d

    if not leaves:
        return LeafClusters(0, 0, 0)
    ids = np.concatenate([np.full(len(p), leaf, np.int64) for leaf, p in leaves.items()])
    points = np.concatenate(list(leaves.values()))
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    label = np.asarray(cloud.cluster_dbscan(eps=CLUSTER_EPS_VOXELS * voxel_m, min_points=4))
    per_leaf = {leaf: len(p) for leaf, p in leaves.items()}
    count = one_leaf = merged = 0
    for c in np.unique(label[label >= 0]):
        members = ids[label == c]
        if len(members) < MIN_LEAF_POINTS:
            continue
        count += 1
        owners, counts = np.unique(members, return_counts=True)
        top = int(np.argmax(counts))
        if counts[top] >= CLUSTER_PURITY * len(members):
            one_leaf += int(counts[top] >= CLUSTER_COVER * per_leaf[int(owners[top])])
        else:
            merged += 1
    return LeafClusters(count, one_leaf, merged)


@dataclass
class PlantEstimate:
    """A plant as measured from a run's views (see :func:`measure`); lengths in metres."""

    depth: str
    views: int
    leaf_count: int
    leaf_area_m2: float
    height_m: float
    crown_diameter_m: float
    convex_hull_volume_m3: float
    mean_inclination_deg: float
    clusters: LeafClusters
    leaves: list[LeafEstimate] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def measure(run_dir: Path, depth: str = "sensor", progress: Callable[[int, int], None] | None = None) -> PlantEstimate:
    """Every estimate of the plant in the complete run ``run_dir`` from its views (the module's
    steps), on the exact depth (``truth``) or the run's sensor's (``sensor``)."""
    from agrisim.plugins.apps.traits.truth import hull_figures

    fused = fuse_views(run_dir, depth, progress=progress)
    seen = [leaf for leaf in leaf_estimates(fused.leaves) if leaf.points >= MIN_LEAF_POINTS]
    body = _without_outliers(fused.plant)
    volume, crown = hull_figures(body)
    area = sum(leaf.area_m2 for leaf in seen)
    return PlantEstimate(
        depth=fused.depth,
        views=fused.views,
        leaf_count=len(seen),
        leaf_area_m2=area,
        height_m=float(body[:, 2].max()) if len(body) else 0.0,
        crown_diameter_m=crown,
        convex_hull_volume_m3=volume,
        mean_inclination_deg=(
            float(np.average([leaf.inclination_deg for leaf in seen], weights=[leaf.area_m2 for leaf in seen]))
            if area > 0
            else 0.0
        ),
        clusters=cluster_leaves({leaf: fused.leaves[leaf] for leaf in (s.id for s in seen)}),
        leaves=seen,
    )


def _without_outliers(points: np.ndarray) -> np.ndarray:
    """``points`` less Open3D's statistical outliers (mean distance to 20 neighbours beyond 2
    standard deviations of the cloud's): what floats free of the plant, such as a sensor's
    flying pixels, would set its height and hull."""
    import open3d as o3d

    if len(points) < 21:
        return points
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    _, kept = cloud.remove_statistical_outlier(nb_neighbors=20, std_ratio=2.0)
    return points[np.asarray(kept, np.int64)]
