"""Point plants at scale: seconds per 1080p view (RGB + labels + depth, the lab's 4 lights, 1
shadow sample, the arms in view) with the raycast renderer for a plant drawn as 100k and 1M
points, against the same plant as its mesh, and the peak memory of each across point sizes.
Every case runs in a fresh process (its own peak RSS). Prints figures; asserts nothing.

    python bench/point_render.py [--plant coltsfoot] [--views 4] [--counts 100000,1000000]
                                 [--sizes 0.0005,0.002,0.008]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402


def one(plant_name: str, count: int, size: float, views: int, resolution: str) -> dict:
    """Render ``views`` views of the plant as ``count`` points of ``size`` (count 0: the mesh)."""
    from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config
    from agrisim.plant_choice import resolve_plant
    from agrisim.plugins.rigs.paper.cell import build_cell, hemisphere
    from agrisim.plugins.rooms.lab.room import build_scene
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.robot.kinematics import ArmKinematics
    from agrisim.scene.camera import preset

    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    points = {"count": count, "size": size} if count else {}
    t0 = time.perf_counter()
    plant = resolve_plant(registry, build_config({"plant": plant_name, "points": points}))
    scene = build_scene(cell, plant)
    t_plant = time.perf_counter() - t0
    camera = preset("rpi3-wide-1080p", resolution)
    kin = {a.name: ArmKinematics(a) for a in cell.arms}
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    setpoints = hemisphere(cell, RoutineConfig())["r1"]
    cams = [setpoints[i].world_T_camera for i in np.linspace(0, len(setpoints) - 1, views).astype(int)]
    spec = registry.get("renderer", "raycast")
    t0 = time.perf_counter()
    renderer = spec.factory(scene, cell, RenderConfig(), spec.options_model(shadow_samples=1))
    t_build = time.perf_counter() - t0
    renderer.render(camera, cams[0], poses)  # warm-up: Dr.Jit compiles its kernels once
    t0 = time.perf_counter()
    labelled = 0
    for T in cams:
        frame = renderer.render(camera, T, poses)
        labelled += int((frame.labels > 0).sum())
    per_view = (time.perf_counter() - t0) / len(cams)
    renderer.close()
    return {
        "count": count,
        "size_mm": size * 1e3 if count else None,
        "plant_s": t_plant,
        "build_s": t_build,
        "per_view_s": per_view,
        "labelled_per_view": labelled / len(cams),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="coltsfoot")
    parser.add_argument("--views", type=int, default=4)
    parser.add_argument("--resolution", default="1920x1080")
    parser.add_argument("--counts", default="100000,1000000")
    parser.add_argument("--sizes", default="0.0005,0.002,0.008", help="point diameters, m (memory across sizes)")
    parser.add_argument("--one", nargs=2, metavar=("COUNT", "SIZE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one(args.plant, int(args.one[0]), float(args.one[1]), args.views, args.resolution)))
        return

    counts = [int(c) for c in args.counts.split(",")]
    sizes = [float(s) for s in args.sizes.split(",")]
    print(f"{args.plant} at {args.resolution}, {args.views} views, raycast with 1 shadow sample; {cpu_model()}")
    print(
        f"{'plant':>16} {'size':>8} {'prepare s':>10} {'build s':>8} {'s/view':>7} {'labelled px':>12} {'peak MB':>8}"
    )
    cases = [(0, 0.0)] + [(n, s) for n in counts for s in sizes]
    for count, size in cases:
        res = subprocess.run(
            [sys.executable, __file__, "--plant", args.plant, "--views", str(args.views), "--resolution", args.resolution,
             "--one", str(count), str(size)],
            capture_output=True, text=True, check=True,
        )  # fmt: skip
        r = json.loads(res.stdout.strip().splitlines()[-1])
        what = "mesh" if not count else f"{count:,} points"
        size_text = "" if not count else f"{r['size_mm']:g} mm"
        print(
            f"{what:>16} {size_text:>8} {r['plant_s']:10.2f} {r['build_s']:8.2f} {r['per_view_s']:7.2f} "
            f"{r['labelled_per_view']:12,.0f} {r['peak_rss_mb']:8.0f}"
        )


if __name__ == "__main__":
    main()
