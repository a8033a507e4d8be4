"""Steps per second of ``agrisim/PlantView-v0``, and where a step's time goes: the arm's IK and
planning, its motion (timing and physics), the render, the fusion into the reconstruction, and
the environment's own coverage and voxel map. Random discrete actions on one plant; prints the
machine (the CPU, and the GPU when Mitsuba runs a CUDA variant) and the figures, asserts nothing.

The steps timed are an episode's first ``--steps`` (it lasts one more): the episode's end, its
reconstruction measured against the truth (Open3D) and its run written, is timed apart, when
the env is closed; without Open3D (a GPU machine carrying bench/device_site.sh --robot) it is
not measured and the steps' figures stand.

    python bench/nextview_speed.py [--plant coltsfoot] [--steps 30] [--resolution 480x270]
        [--renderer raycast] [--set physics.backend=kinematic ...] [--out FIGURES.json]

On a GPU machine with Python 3.12 and no package index: ``bash bench/device_site.sh SITE.tar.xz
--robot`` here, then there ``bash bench/device_install.sh SITE.tar.xz /tmp/site``, ``export
PYTHONPATH=/tmp/site:/tmp/site/cmeel.prefix/lib/python3.12/site-packages`` and this script with
``--set physics.backend=kinematic --set renderer.raycast.arm_triangles=0`` (no pybullet nor
Open3D there) and ``--set renderer.raycast.variant=cuda`` (or ``llvm``); a first run of
``--steps 2`` fills Dr.Jit's kernel cache, as a machine that has run it before has it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model, gpu_name  # noqa: E402

#: the episode's stages (Episode.wall_s) a step's cost is split into
STAGES = {
    "plan": ("ik", "plan", "parametrize", "joint_check"),
    "move": ("execute",),
    "render": ("render", "imager", "sensor"),
    "write (the run's files, Rerun)": ("capture",),
    "fuse": ("recon",),
}


def mitsuba_variant() -> str:
    """The Mitsuba variant the process renders with (one a process), "" if Mitsuba is not loaded."""
    mi = sys.modules.get("mitsuba")
    return str(mi.variant() or "") if mi is not None else ""


def end_episode(env: Any) -> float | str:
    """Close ``env``, which ends its episode (the reconstruction measured, the run written):
    the seconds it took, or why it was not measured (no Open3D here)."""
    t0 = time.perf_counter()
    try:
        env.close()
    except Exception as exc:  # the episode wraps a backend's error (BackendFailure from ImportError)
        cause = exc.__cause__ or exc
        if not isinstance(cause, ImportError):
            raise
        env.close()  # the episode is closed already: this removes its directory
        return f"not measured ({type(cause).__name__}: {cause})"
    return time.perf_counter() - t0


def main() -> None:
    from agrisim.plugins.apps.flags import apply_sets
    from agrisim.plugins.apps.nextview.env import PlantViewEnv

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="coltsfoot")
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--resolution", default="480x270")
    parser.add_argument("--renderer", default="raycast")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--out", type=Path, help="also write the figures here, as JSON")
    args = parser.parse_args()
    overrides: dict = {}
    apply_sets(overrides, args.set)

    env = PlantViewEnv(
        plant=args.plant,
        resolution=args.resolution,
        renderer=args.renderer,
        max_views=args.steps + 1,
        config=overrides,
    )
    t0 = time.perf_counter()
    env.reset(seed=0)
    reset_s = time.perf_counter() - t0
    episode = env.episode
    assert episode is not None
    before = dict(episode.wall_s)
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    for _ in range(args.steps):
        env.step(int(rng.integers(env.action_space.n)))
    total = time.perf_counter() - start
    wall = episode.wall_s
    spent = {name: sum(wall.get(s, 0.0) - before.get(s, 0.0) for s in stages) for name, stages in STAGES.items()}
    spent["coverage and map"] = env.timing["coverage"] + env.timing["map"]
    spent["other"] = total - sum(spent.values())
    end = end_episode(env)

    # the machine: the CPU always (the planning, the physics, the fusion run there), the GPU too
    # when the renderer ran a CUDA variant (asked for, or "auto" finding one)
    variant = mitsuba_variant()
    cpu = cpu_model()
    gpu = gpu_name() if variant.startswith("cuda") or "'cuda'" in str(overrides) else None
    machine = f"{cpu}, {os.cpu_count()} cores" + (f", {gpu}" if gpu else "")
    renderer = f"{args.renderer} ({variant})" if variant else args.renderer
    settings = "".join(f"; {s}" for s in args.set)
    print(f"{machine}; {args.plant}, {args.resolution}, {renderer}, {args.steps} steps{settings}")
    ended = f"{end:.1f} s" if isinstance(end, float) else end
    print(
        f"reset {reset_s:.1f} s (plant, scene, renderer, truth); {args.steps / total:.2f} steps/s; "
        f"episode end (reconstruction measured, run written) {ended}"
    )
    print("| part of a step | ms | share |")
    print("|---|---|---|")
    for name, seconds in spent.items():
        print(f"| {name} | {1e3 * seconds / args.steps:.0f} | {100 * seconds / total:.0f}% |")
    if args.out:
        figures = {
            "cpu": cpu,
            "cores": os.cpu_count(),
            "gpu": gpu,
            "plant": args.plant,
            "resolution": args.resolution,
            "renderer": args.renderer,
            "variant": variant or None,
            "settings": args.set,
            "steps": args.steps,
            "reset_s": round(reset_s, 3),
            "steps_per_s": round(args.steps / total, 4),
            "ms_per_step": {name: round(1e3 * seconds / args.steps, 2) for name, seconds in spent.items()},
            "episode_end_s": round(end, 3) if isinstance(end, float) else None,
        }
        args.out.write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
