"""Reconstruction of the paper's 100 views at 1080p: seconds for agrisim's incremental voxel grid
against the paper's way (re-downsample the growing cloud whenever it passes 100k points) and a
single downsample of everything, all measured in one run on the same views; then TSDF fusion
and the accuracy metrics. Prints figures; asserts nothing.

    python bench/recon_views.py [--plant indian_cress] [--views 100] [--resolution 1920x1080]

The views are rendered first (robots hidden, no shadows: reconstruction only reads labels and
depth) and held in memory, so rendering is not part of the reconstruction's time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import open3d as o3d

from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config
from agrisim.evaluation.metrics import GroundTruth
from agrisim.evaluation.session import ReconSession
from agrisim.evaluation.views import View, backproject
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.recon.pointcloud import PointCloudReconstructor
from agrisim.plugins.recon.tsdf import TsdfReconstructor
from agrisim.plugins.rigs.paper.cell import build_cell, hemisphere
from agrisim.plugins.rooms.lab.room import build_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.scene.camera import preset


def _pcd(points: np.ndarray) -> o3d.geometry.PointCloud:
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="indian_cress")
    parser.add_argument("--views", type=int, default=100)
    parser.add_argument("--resolution", default="1920x1080")
    args = parser.parse_args()

    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    scene = build_scene(cell, resolve_plant(registry, build_config({"plant": args.plant})))
    camera = preset("rpi3-wide-1080p", args.resolution)
    poses = [sp.world_T_camera for sps in hemisphere(cell, RoutineConfig()).values() for sp in sps][: args.views]
    spec = registry.get("renderer", "raycast")
    renderer = spec.factory(scene, cell, RenderConfig(hide_robots=True), spec.options_model(shadow_samples=0))
    t0 = time.perf_counter()
    views = []
    for i, T in enumerate(poses):
        f = renderer.render(camera, T, {})
        views.append(View(f"v{i:03d}", camera, T, f.stored()))
    print(
        f"{args.plant}, {len(views)} views at {camera.width}x{camera.height}: rendered in {time.perf_counter() - t0:.1f} s"
    )

    t0 = time.perf_counter()
    per_view = [backproject(v, v.images.labels != 0, 1.0) for v in views]
    t_bp = time.perf_counter() - t0
    total = sum(len(p) for p, _ in per_view)
    print(f"  back-projection: {t_bp / len(views) * 1e3:.1f} ms per view, {total:,} plant points in all")

    # agrisim: the incremental voxel grid (back-projection included)
    t0 = time.perf_counter()
    recon = PointCloudReconstructor(scene.labels)
    for v in views:
        recon.integrate(v)
    ours = recon.result().clouds["plant"]
    t_ours = time.perf_counter() - t0

    # the paper's way: concatenate, re-downsample whenever the cloud passes 100k points
    t0 = time.perf_counter()
    cloud = o3d.geometry.PointCloud()
    for points, _ in per_view:
        cloud += _pcd(points)
        if len(cloud.points) > 100_000:
            cloud = cloud.voxel_down_sample(0.001)
    paper = cloud.voxel_down_sample(0.001)
    t_paper = time.perf_counter() - t0 + t_bp

    # everything at once, one downsample
    t0 = time.perf_counter()
    once = _pcd(np.concatenate([p for p, _ in per_view])).voxel_down_sample(0.001)
    t_once = time.perf_counter() - t0 + t_bp

    print(f"  pointcloud (incremental grid): {t_ours:6.1f} s  {len(ours):,} points")
    print(
        f"  paper's re-downsampling:       {t_paper:6.1f} s  {len(paper.points):,} points  ({t_paper / t_ours:.1f}x ours)"
    )
    print(
        f"  one downsample at the end:     {t_once:6.1f} s  {len(once.points):,} points  ({t_once / t_ours:.1f}x ours)"
    )

    truth = GroundTruth.sample(scene.mesh(scene.plant), 500_000)
    for name, make in (
        ("pointcloud", lambda: PointCloudReconstructor(scene.labels)),
        ("tsdf", lambda: TsdfReconstructor(scene.labels)),
    ):
        session = ReconSession(make(), scene.labels, truth, [1.0, 2.0, 5.0])
        t0 = time.perf_counter()
        for v in views:
            session.add(v)
        t_add = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, metrics = session.finish()
        t_fin = time.perf_counter() - t0
        row = metrics["labels"]["plant"]
        print(
            f"  {name:10s} session: {t_add:6.1f} s for {len(views)} views (visibility counts included), "
            f"{t_fin:5.1f} s to finish + measure; precision@2mm {row['precision']['2']:.4f}, "
            f"recall@2mm {row['recall']['2']:.3f} (visible {row['recall_visible']['2']:.3f}), "
            f"F@5mm {row['fscore']['5']:.3f}, Chamfer {row['chamfer_mm']:.2f} mm"
        )


if __name__ == "__main__":
    main()
