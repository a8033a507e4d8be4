"""What each procedural species costs: triangles, seconds to build, and seconds a ``raycast``
view (RGB + labels + depth, arms posed, the routine's setpoints) at 1080p; with ``--before CMD``
the same measured for another checkout's code in the same run, species by species alternately
(each in a fresh process), with the ratios. Prints the CPU model and figures; asserts nothing.

    python bench/plant_render_cost.py [--views 4] [--resolution 1920x1080] [--species coltsfoot ...]
    python bench/plant_render_cost.py --before "../before/.venv/bin/python"   # a checkout's own environment
"""

from __future__ import annotations

import argparse
import json
import shlex
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402


def measure(species: str, views: int, resolution: str) -> dict[str, float]:
    """Triangles, build seconds (median of 3) and raycast seconds a view (median) of one species."""
    import numpy as np

    from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config
    from agrisim.plant_choice import resolve_plant
    from agrisim.plugins.plants.procedural import grow
    from agrisim.plugins.rigs.paper.cell import build_cell, hemisphere
    from agrisim.plugins.rooms.lab.room import build_scene
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.robot.kinematics import ArmKinematics
    from agrisim.scene.camera import preset

    grow(species, 0)  # (a first build may fill caches)
    builds = []
    for _ in range(3):
        t0 = time.perf_counter()
        plant = grow(species, 0)
        builds.append(time.perf_counter() - t0)
    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    scene = build_scene(cell, resolve_plant(registry, build_config({"plant": species})))
    poses = {a.name: ArmKinematics(a).link_poses(np.array(a.home)) for a in cell.arms}
    points = hemisphere(cell, RoutineConfig())
    setpoints = [p for robot in sorted(points) for p in points[robot][:: max(1, len(points[robot]) // views)]][
        : views + 1
    ]
    spec = registry.get("renderer", "raycast")
    renderer = spec.factory(scene, cell, RenderConfig(), spec.options_model())
    camera = preset("rpi3-wide-1080p", resolution)
    seconds = []
    for i, p in enumerate(setpoints):
        t0 = time.perf_counter()
        renderer.render(camera, p.world_T_camera, poses)
        if i:  # (the first compiles)
            seconds.append(time.perf_counter() - t0)
    renderer.close()
    return {
        "triangles": len(plant.mesh.faces),
        "build_s": statistics.median(builds),
        "view_s": statistics.median(seconds),
    }


def child(cmd: list[str], species: str, args: argparse.Namespace) -> dict[str, float]:
    out = subprocess.run(
        [*cmd, __file__, "--child", species, "--views", str(args.views), "--resolution", args.resolution],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=int, default=4)
    parser.add_argument("--resolution", default="1920x1080")
    from agrisim.plugins.plants.procedural.species import SPECIES

    parser.add_argument("--species", nargs="+", default=list(SPECIES))
    parser.add_argument("--before", help="the command (a Python interpreter) whose agrisim is the code to compare")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(measure(args.child, args.views, args.resolution)))
        return
    print(f"CPU: {cpu_model()}; raycast at {args.resolution}, {args.views} views a species after the first")
    header = "| species | triangles | build s | raycast s a view |"
    if args.before:
        header = "| species | triangles before | now | build s before | now | raycast s a view before | now | ratio |"
    print(header)
    print("|" + "---|" * (header.count("|") - 1))
    for species in args.species:
        now = child([sys.executable], species, args)
        if not args.before:
            print(f"| {species} | {now['triangles']:,} | {now['build_s']:.3f} | {now['view_s']:.3f} |")
            continue
        old = child(shlex.split(args.before), species, args)
        print(
            f"| {species} | {old['triangles']:,} | {now['triangles']:,} | {old['build_s']:.3f} | "
            f"{now['build_s']:.3f} | {old['view_s']:.3f} | {now['view_s']:.3f} | {now['view_s'] / old['view_s']:.2f} |"
        )


if __name__ == "__main__":
    main()
