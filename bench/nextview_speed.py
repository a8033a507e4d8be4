"""Steps per second of ``agrisim/PlantView-v0``, and where a step's time goes: the arm's IK and
planning, its motion (timing and physics), the render, the fusion into the reconstruction, and
the environment's own coverage and voxel map. Random discrete actions on one plant; prints the
machine and the figures, asserts nothing.

    python bench/nextview_speed.py [--plant coltsfoot] [--steps 30] [--resolution 480x270]
        [--renderer raycast] [--set physics.backend=kinematic ...]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

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


def main() -> None:
    from agrisim.app.arguments import apply_sets
    from agrisim.envs.plant_view import PlantViewEnv

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="coltsfoot")
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--resolution", default="480x270")
    parser.add_argument("--renderer", default="raycast")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    overrides: dict = {}
    apply_sets(overrides, args.set)
    where = gpu_name() if args.renderer == "mitsuba" and "cuda" in str(overrides) else cpu_model()
    print(f"{where}, {os.cpu_count()} cores; {args.plant}, {args.resolution}, {args.renderer}, {args.steps} steps")

    env = PlantViewEnv(
        plant=args.plant, resolution=args.resolution, renderer=args.renderer, max_views=args.steps, config=overrides
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
    env.close()
    print(f"reset {reset_s:.1f} s (plant, scene, renderer, truth); {args.steps / total:.2f} steps/s")
    print("| part of a step | ms | share |")
    print("|---|---|---|")
    for name, seconds in spent.items():
        print(f"| {name} | {1e3 * seconds / args.steps:.0f} | {100 * seconds / total:.0f}% |")


if __name__ == "__main__":
    main()
