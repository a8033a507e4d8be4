"""What a phenotyping pipeline measures of a plant from a run's views, the first step: each
leaf's points, fused from every view by its instance mask (the id :mod:`agrisim.traits.truth`
gives the same leaf, so an estimate meets its truth by id).

Each view's pixels of one leaf instance (and a depth within ``max_depth``) are back-projected
through the run's camera, lens included, and moved to the world by the view's pose
(:func:`agrisim.evaluation.views.backproject`); the views' points of a leaf are merged on a
``voxel_m`` grid (the mean of each voxel's points), as the ``pointcloud`` reconstructor merges a
label's. ``depth`` is the run's exact depth (``truth``) or its depth sensor's (``sensor``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agrisim.errors import UserError
from agrisim.evaluation.session import capture_order
from agrisim.evaluation.views import backproject, load_view
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json, read_run

#: voxel of the merged leaf clouds, m (the paper's 1 mm)
VOXEL_M = 1e-3
#: depth beyond which pixels are dropped, m (the paper's 1 m)
MAX_DEPTH_M = 1.0


def leaf_clouds(
    run_dir: Path,
    depth: str = "truth",
    voxel_m: float = VOXEL_M,
    max_depth_m: float = MAX_DEPTH_M,
    progress: Callable[[int, int], None] | None = None,
) -> dict[int, np.ndarray]:
    """Each leaf's fused points (world frame, N x 3), by leaf instance id, from the complete run
    in ``run_dir``. A run without instance masks is refused with a UserError."""
    run, cameras = read_run(Path(run_dir))
    frames = capture_order(run, sorted(run.get("frames_complete") or []))
    if not frames or not layout.image(run_dir, "instances", frames[0]).is_file():
        raise UserError(
            f"the run in {run_dir} has no instance masks (instances/): per-leaf estimates need them "
            "(a plant whose leaves are instances, rendered by raycast or mitsuba)"
        )
    camera = camera_from_json(cameras["intrinsics"])
    ids: list[np.ndarray] = []
    points: list[np.ndarray] = []
    for i, frame in enumerate(frames):
        T = np.asarray(cameras["frames"][frame]["world_T_camera"], np.float64)
        view = load_view(Path(run_dir), frame, camera, T, depth)
        instances = view.images.instances
        assert instances is not None
        leafy = instances > 0
        p, _ = backproject(view, leafy, max_depth_m)
        if len(p):
            # backproject keeps the mask's pixels in row-major order where the depth is kept
            v, u = np.nonzero(leafy & (view.images.depth > 0))
            near = view.images.depth[v, u] <= np.float32(max_depth_m)
            ids.append(instances[v[near], u[near]].astype(np.int64))
            points.append(p)
        if progress is not None:
            progress(i + 1, len(frames))
    if not points:
        return {}
    return _merged(np.concatenate(ids), np.concatenate(points), voxel_m)


def _merged(ids: np.ndarray, points: np.ndarray, voxel_m: float) -> dict[int, np.ndarray]:
    """Points merged per leaf on a ``voxel_m`` grid: each occupied voxel's mean point."""
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
    """Each leaf's area, inclination and azimuth from its fused points (:func:`leaf_clouds`).

    - Area: the surface Open3D's ball pivoting (Bernardini et al. 1999) lays on the points, with
      balls of 1.5 and 3 times their mean spacing (at least a voxel): it follows one sheet of points as a leaf is one sheet, where a
      Poisson surface closes it into a shell (twice the area) and a 3D alpha shape thickens it.
      Holes the views left stay holes: an unseen part of a leaf is not counted.
    - Inclination and azimuth: each point's normal from its neighbours within 3 spacings (PCA,
      Open3D), turned upward, averaged as :mod:`agrisim.traits.truth` averages the surface's.
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
