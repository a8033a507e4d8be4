"""What a view of a bench costs against the number of plants on it: seconds per view (RGB,
labels, depth, leaf instances and the plants' ids in one pass) for a renderer, with 1 plant and
with benches of more, the same views of the same first plant (its hemisphere on the gantry, its
neighbours around and behind it), and each bench's cost as a multiple of the one plant's,
measured in one run. The first plant stands on the cell's centre on every bench (the grid's most
central pot), so every bench is seen through the same camera poses. Prints figures; asserts
nothing.

    python bench/bench_view_cost.py                          # raycast on the CPU (LLVM), 1080p
    python bench/bench_view_cost.py --variant cuda           # ... on an NVIDIA GPU (OptiX)
    python bench/bench_view_cost.py --benches 1x1,2x2,4x6 --views 4 --resolution 960x540

The goal (issue 62): a 1080p raycast view of a 24-plant bench (4x6) at most 2x a one-plant view.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from agrisim.config import build_config
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.rigs.gantry.cell import hemisphere_views
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.kinematics import ArmKinematics
from agrisim.scene.camera import preset
from agrisim.validation import open_rig


def cpu_name() -> str:
    """The CPU's model and its widest vector ISA, as every absolute figure names them."""
    model = platform.processor() or "unknown CPU"
    try:
        text = open("/proc/cpuinfo").read()
        model = next(line.split(":", 1)[1].strip() for line in text.splitlines() if line.startswith("model name"))
        flags = next(line for line in text.splitlines() if line.startswith("flags"))
        isa = "AVX-512" if " avx512f" in flags else "AVX2" if " avx2" in flags else "SSE"
        return f"{model} ({isa})"
    except (OSError, StopIteration):
        return model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="indian_cress")
    parser.add_argument("--benches", default="1x1,2x2,2x4,4x6", help="grids RxC; 1x1 is the one plant, no bench")
    parser.add_argument("--spacing", type=float, default=0.5)
    parser.add_argument("--views", type=int, default=6)
    parser.add_argument("--repeats", type=int, default=2, help="passes over the views; the fastest counts")
    parser.add_argument("--resolution", default="1920x1080")
    parser.add_argument("--variant", choices=["llvm", "cuda"], default="llvm")
    parser.add_argument("--renderer", default="raycast")
    args = parser.parse_args()

    registry = Registry(make_plugin_manager())
    camera = preset("rpi3-wide-1080p", args.resolution)
    where = cpu_name() if args.variant == "llvm" else "the GPU (see nvidia-smi)"
    print(
        f"{args.renderer} ({args.variant}) on {where}; {camera.width}x{camera.height}, {args.plant}, spacing {args.spacing} m"
    )
    print("| plants | plant triangles | s per view | x one plant |")
    print("|---:|---:|---:|---:|")
    base = None
    for grid in args.benches.split(","):
        rows, cols = (int(n) for n in grid.split("x"))
        settings = {"plant": args.plant, "rig": {"backend": "gantry"}}
        if rows * cols > 1:  # the grid's most central pot on the plant centre, listed first
            spots = sorted(
                ((c - (cols - 1) // 2) * args.spacing, (r - (rows - 1) // 2) * args.spacing)
                for r in range(rows)
                for c in range(cols)
            )
            spots.sort(key=lambda xy: xy != (0.0, 0.0))
            settings["bench"] = {"plants": [{"x": x, "y": y} for x, y in spots]}
        config = build_config(settings, {"renderer": {args.renderer: {"variant": args.variant}}})
        rig, cell = open_rig(config, registry)
        plant = resolve_plant(registry, config)
        room = registry.build("room", registry.get("room", "lab"), cell, registry.get("room", "lab").options_model())
        scene = room.scene(plant, seed=config.pcg_seed, labels="plant")
        scene.bench = list(plant.bench)
        centre = cell.plant_center  # the first plant's, on every bench: the same views
        routine = config.routine.model_copy(update={"setpoints": f"2x{max(1, args.views // 2)}"})
        views = [T for _, _, T in hemisphere_views(centre, routine)][: args.views]
        arm = cell.arms[0]
        poses = {arm.name: ArmKinematics(arm).link_poses(np.array(arm.home))}
        spec = registry.get("renderer", args.renderer)
        options = spec.options_model(**config.renderer.options_for(args.renderer))
        renderer = spec.factory(scene, cell, config.render, options)
        renderer.render(camera, views[0], poses)  # warm-up: the scene's build, the kernels' compilation
        best = float("inf")
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            for T in views:
                frame = renderer.render(camera, T, poses)
            best = min(best, (time.perf_counter() - t0) / len(views))
        renderer.close()
        n = max(1, len(cell.bench))
        assert n == 1 or frame.plants is not None
        base = base or best
        print(f"| {n} | {len(plant.mesh.faces):,} | {best:.3f} | {best / base:.2f} |")


if __name__ == "__main__":
    main()
