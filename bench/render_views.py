"""Seconds per 1080p view (RGB + labels + depth, the lab's 4 lights, 1 shadow sample) for the
``raycast`` and ``pybullet`` renderers on the same scene and camera poses, and their ratio,
measured in one run. Prints figures; asserts nothing.

    python bench/render_views.py [--plant indian_cress] [--views 6] [--resolution 1920x1080]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.rigs.paper.cell import build_cell, hemisphere
from agrisim.plugins.rooms.lab.room import build_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.kinematics import ArmKinematics
from agrisim.scene.camera import preset


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="indian_cress")
    parser.add_argument("--views", type=int, default=6)
    parser.add_argument("--resolution", default="1920x1080")
    parser.add_argument("--shadow-samples", type=int, default=1)
    args = parser.parse_args()

    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    plant = resolve_plant(registry, build_config({"plant": args.plant}))
    scene = build_scene(cell, plant)
    camera = preset("rpi3-wide-1080p", args.resolution)
    kin = {a.name: ArmKinematics(a) for a in cell.arms}
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    setpoints = hemisphere(cell, RoutineConfig())["r1"]
    views = [setpoints[i].world_T_camera for i in np.linspace(0, len(setpoints) - 1, args.views).astype(int)]
    settings = RenderConfig()
    print(
        f"{args.plant}: {len(plant.mesh.faces):,} plant triangles, {sum(len(m.faces) for m in scene.meshes):,} in the scene; "
        f"{camera.width}x{camera.height}, {len(scene.lights)} lights, {args.shadow_samples} shadow sample(s)"
    )
    per_view = {}
    for name in ("raycast", "pybullet"):
        spec = registry.get("renderer", name)
        options = {"shadow_samples": args.shadow_samples} if name == "raycast" else {}
        renderer = spec.factory(scene, cell, settings, spec.options_model(**options))
        renderer.render(camera, views[0], poses)  # warm-up: scene building, caches
        t0 = time.perf_counter()
        for T in views:
            renderer.render(camera, T, poses)
        per_view[name] = (time.perf_counter() - t0) / len(views)
        renderer.close()
        print(f"  {name:8s}: {per_view[name]:.2f} s per view")
    print(f"  raycast is {per_view['pybullet'] / per_view['raycast']:.1f}x faster than pybullet's TinyRenderer")


if __name__ == "__main__":
    main()
