"""Policies of ``agrisim nextview`` replayed on every candidate's look, without the arms: a quick
stand-in for the command where its episodes would take too long (ten species x five seeds at
480x270 is over an hour on two cores, most of it the paper's 100 views and the arms' planning).

Each plant and seed is grown as the command grows it (``env.reset(seed=s, options={"plant_seed":
s, "pcg_seed": 42})``); the view from every candidate is taken once (``env.look_from``: the arms
left out), and every policy then chooses its views in turn from those looks: the coverage the
environment counts (:class:`SurfaceCoverage`), the voxel map fused from the same depth and
labels, the cameras moved to each view taken. Unlike the command: no candidate is out of reach,
no arm stands in a view, and motion is the cameras' straight-line travel (m), not the arms'
time. Random and oracle reproduce the command's coverage (hydrangea, seeds 0-4: 0.557 and
0.669 after 5 views both ways). Prints the share of the oracle's gap each policy closes at
each budget (per seed, averaged, ± half its 95% t interval; in brackets the same ratio of the
means) and writes every curve as JSON.

    python bench/nextview_replay.py --plant hydrangea coltsfoot --seeds 5 --budgets 5,10 \
        --policies spread,spread-surface [--resolution 480x270] [--out replay.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats as sps

from agrisim.evaluation.views import View
from agrisim.plugins.apps.nextview.env import PlantViewEnv
from agrisim.plugins.apps.nextview.occupancy import VoxelMap
from agrisim.plugins.apps.nextview.policies import POLICIES


class Replay:
    """What a policy reads of a PlantViewEnv, served from the looks taken once."""

    def __init__(self, env: PlantViewEnv, looks: list[View], visible: list[Any], views: int) -> None:
        self.candidates, self.camera, self.arms = env.candidates, env.camera, env.arms
        self.looks, self.visible = looks, visible
        self.coverage = type(env.coverage)(env.coverage.truth)
        self.voxels = VoxelMap.around(env._centre, *env._grid[::-1])
        self.cameras = {arm: env.camera_position(arm) for arm in env.arms}
        self.views, self.max_views, self.travel_m = 0, views, 0.0

    def look_from(self, world_T_camera: np.ndarray) -> View:
        return next(v for v in self.looks if np.array_equal(v.world_T_camera, world_T_camera))

    def camera_position(self, robot: str) -> np.ndarray:
        return self.cameras[robot]

    def step(self, i: int, fuse: bool) -> None:
        sp, view = self.candidates[i], self.looks[i]
        self.travel_m += float(np.linalg.norm(sp.world_T_camera[:3, 3] - self.cameras[sp.robot]))
        self.cameras[sp.robot] = sp.world_T_camera[:3, 3]
        seen, side = self.visible[i]
        self.coverage.seen[seen, side] = True
        if fuse:  # the map only for the policies that read it: it is most of a replay's time
            self.voxels.integrate(view.camera, view.world_T_camera, view.images.depth, view.images.labels)
        self.views += 1


def replay(plant: str, seed: int, policies: list[str], views: int, resolution: str) -> dict[str, Any]:
    env = PlantViewEnv(plant=plant, resolution=resolution)
    env.reset(seed=seed, options={"plant_seed": seed, "pcg_seed": 42})
    looks = [env.look_from(sp.world_T_camera) for sp in env.candidates]
    visible = [env.coverage.visible(v) for v in looks]  # the env's coverage is empty: all they see
    out: dict[str, Any] = {}
    for name in policies:
        t0 = time.perf_counter()
        run = Replay(env, looks, visible, views)
        policy = POLICIES[name](seed)
        policy.reset(run)  # type: ignore[arg-type]
        coverage, travel = [], []
        fuse = "surface" in name or "volumetric" in name
        for _ in range(views):
            i = policy.act(run, {})  # type: ignore[arg-type]
            run.step(i, fuse)
            policy.observe(i, {"reached": True})
            coverage.append(run.coverage.value)
            travel.append(run.travel_m)
        out[name] = {"coverage": coverage, "travel_m": travel, "wall_s": time.perf_counter() - t0}
    env.close()
    return out


def t_half(values: np.ndarray) -> float:
    if len(values) < 2:
        return float("nan")
    return float(sps.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values)))


def table(results: dict[str, dict[int, dict[str, Any]]], policies: list[str], budgets: list[int]) -> str:
    heads = [f"{p} @{b}" for p in policies for b in budgets]
    lines = ["| plant | " + " | ".join(heads) + " |", "|---" * (len(heads) + 1) + "|"]
    for plant, seeds in results.items():
        cells = []
        for name in policies:
            for b in budgets:
                c, r, o = (
                    np.array([s[p]["coverage"][b - 1] for s in seeds.values()]) for p in (name, "random", "oracle")
                )
                ok = o - r > 1e-9
                share = (c[ok] - r[ok]) / (o[ok] - r[ok])
                of_means = (c.mean() - r.mean()) / (o.mean() - r.mean())
                cells.append(f"{share.mean():+.2f} ±{t_half(share):.2f} ({of_means:+.2f})")
        lines.append(f"| {plant.replace('_', ' ')} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plant", nargs="+", default=["hydrangea"])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--budgets", default="5,10")
    parser.add_argument("--policies", default="spread")
    parser.add_argument("--resolution", default="480x270")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    budgets = sorted(int(b) for b in args.budgets.split(","))
    policies = [p for p in args.policies.split(",") if p not in ("random", "oracle")]
    results: dict[str, dict[int, dict[str, Any]]] = {}
    for plant in args.plant:
        for seed in range(args.seeds):
            results.setdefault(plant, {})[seed] = replay(
                plant, seed, ["random", "oracle", *policies], max(budgets), args.resolution
            )
            print(f"{plant} seed {seed} done", file=sys.stderr)
    if args.out:
        args.out.write_text(json.dumps({"budgets": budgets, "plants": results}))
    print(table(results, ["random", "oracle", *policies][2:], budgets))
    return 0


if __name__ == "__main__":
    sys.exit(main())
