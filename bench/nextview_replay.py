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
        --policies spread,spread-surface [--resolution 480x270] [--out replay.json] [--cache DIR]

With ``--cache DIR`` the looks are read from ``bench/nextview_cache.py``'s files (made there
first where missing), not taken again: the same coverage and the same map, voxel for voxel,
without rendering (``--plant all``: the ten species). It also prints, for each policy, the
camera travel it needs to reach random's coverage after the largest budget, as a share of
random's travel then.
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
from agrisim.plugins.apps.nextview.coverage import SurfaceCoverage
from agrisim.plugins.apps.nextview.env import PlantViewEnv
from agrisim.plugins.apps.nextview.occupancy import VoxelMap
from agrisim.plugins.apps.nextview.policies import POLICIES
from agrisim.robot.setpoints import Setpoint
from agrisim.scene.camera import CameraModel

sys.path.insert(0, str(Path(__file__).parent))
from nextview_cache import SPECIES, build, cache_path, full_images  # noqa: E402

#: the policies that read the voxel map: the replay fuses every view for them only
MAP_POLICIES = ("volumetric", "surface", "learned")


class Replay:
    """What a policy reads of a PlantViewEnv, served from the looks taken once."""

    def __init__(self, env: PlantViewEnv, looks: list[View], visible: list[Any], views: int) -> None:
        self.candidates, self.camera, self.arms = env.candidates, env.camera, env.arms
        self.plant = env.config.plant
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


class CachedCoverage(SurfaceCoverage):
    """The environment's coverage, its looks' visibility read from the cache."""

    def __init__(self, sheet: np.ndarray, visible: list[tuple[np.ndarray, np.ndarray]]) -> None:
        self.sheet, self.cached = sheet, visible
        self.seen = np.zeros((len(sheet), 2), bool)

    def visible(self, view: Any) -> tuple[np.ndarray, np.ndarray]:
        """What look ``view`` sees that is not yet fully seen."""
        seen, side = self.cached[view.index]
        keep = ~self.seen[seen, side]
        return seen[keep], side[keep]


class Look:
    """A cached look as a View reads: the full images rebuilt when first asked for."""

    def __init__(self, record: Any, index: int, camera: CameraModel, world_T_camera: np.ndarray) -> None:
        self.record, self.index, self.camera, self.world_T_camera = record, index, camera, world_T_camera
        self._images: Any = None

    @property
    def images(self) -> Any:
        if self._images is None:
            depth, labels = full_images(self.record, self.index)
            self._images = type("Images", (), {"depth": depth, "labels": labels})()
        return self._images


class CachedReplay(Replay):
    """:class:`Replay` from a cache file of ``bench/nextview_cache.py``, without an environment."""

    def __init__(self, record: Any, views: int) -> None:
        w, h, fx, fy, cx, cy = record["intrinsics"]
        self.camera = CameraModel(int(w), int(h), float(fx), float(fy), float(cx), float(cy))
        self.plant = str(record["plant"])
        self.arms = [str(a) for a in record["arms"]]
        self.candidates = [
            Setpoint(str(r), i, p) for i, (r, p) in enumerate(zip(record["robots"], record["poses"], strict=True))
        ]
        self.looks = [Look(record, i, self.camera, sp.world_T_camera) for i, sp in enumerate(self.candidates)]
        off, idx, side = record["vis_off"], record["vis_idx"], record["vis_side"]
        self.visible = [
            (idx[a:b].astype(np.int64), side[a:b].astype(np.int64)) for a, b in zip(off[:-1], off[1:], strict=True)
        ]
        self.coverage = CachedCoverage(record["sheet"], self.visible)
        cells, size = record["grid"]
        self.voxels = VoxelMap.around(record["centre"], float(size), int(cells))
        self.cameras = {a: np.asarray(c, np.float64) for a, c in zip(self.arms, record["arm_cameras"], strict=True)}
        self.views, self.max_views, self.travel_m = 0, views, 0.0

    def look_from(self, world_T_camera: Any) -> Any:
        return next(v for v in self.looks if np.array_equal(v.world_T_camera, world_T_camera))


def load_record(cache: Path, plant: str, seed: int, resolution: str) -> dict[str, Any]:
    """A plant and seed's cache record, made first where missing."""
    path = cache_path(cache, plant, seed, resolution)
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **build(plant, seed, resolution))
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def run_policy(run: Replay, name: str, seed: int, views: int) -> dict[str, Any]:
    """One policy's episode on a replay: its coverage and travel after each view."""
    t0 = time.perf_counter()
    policy = POLICIES[name](seed)
    policy.reset(run)  # type: ignore[arg-type]
    coverage, travel, chosen = [], [], []
    fuse = any(p in name for p in MAP_POLICIES)
    for _ in range(views):
        i = policy.act(run, {})  # type: ignore[arg-type]
        run.step(i, fuse)
        policy.observe(i, {"reached": True})
        coverage.append(run.coverage.value)
        travel.append(run.travel_m)
        chosen.append(int(i))
    return {"coverage": coverage, "travel_m": travel, "views": chosen, "wall_s": time.perf_counter() - t0}


def replay_cached(
    cache: Path, plant: str, seed: int, policies: list[str], views: int, resolution: str
) -> dict[str, Any]:
    """:func:`replay` from the cache."""
    record = load_record(cache, plant, seed, resolution)
    return {name: run_policy(CachedReplay(record, views), name, seed, views) for name in policies}


def replay(plant: str, seed: int, policies: list[str], views: int, resolution: str) -> dict[str, Any]:
    env = PlantViewEnv(plant=plant, resolution=resolution)
    env.reset(seed=seed, options={"plant_seed": seed, "pcg_seed": 42})
    looks = [env.look_from(sp.world_T_camera) for sp in env.candidates]
    visible = [env.coverage.visible(v) for v in looks]  # the env's coverage is empty: all they see
    out = {name: run_policy(Replay(env, looks, visible, views), name, seed, views) for name in policies}
    env.close()
    return out


def t_half(values: np.ndarray) -> float:
    if len(values) < 2:
        return float("nan")
    return float(sps.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values)))


def shares(seeds: dict[int, dict[str, Any]], name: str, b: int) -> tuple[np.ndarray, float]:
    """Each seed's share of the oracle's gap ``name`` closes after ``b`` views (seeds where the
    oracle leads random left out), and the same ratio of the means."""
    c, r, o = (np.array([s[p]["coverage"][b - 1] for s in seeds.values()]) for p in (name, "random", "oracle"))
    ok = o - r > 1e-9
    return (c[ok] - r[ok]) / (o[ok] - r[ok]), float((c.mean() - r.mean()) / (o.mean() - r.mean()))


def travel_to(curve: dict[str, Any], target: float) -> float:
    """The camera travel (m) until ``curve``'s coverage first reaches ``target``, linear between
    views (NaN where it never does)."""
    cov, travel = np.asarray(curve["coverage"]), np.asarray(curve["travel_m"])
    at = np.flatnonzero(cov >= target - 1e-12)
    if not len(at):
        return float("nan")
    k = int(at[0])
    if k == 0:
        return float(travel[0])
    f = (target - cov[k - 1]) / max(cov[k] - cov[k - 1], 1e-12)
    return float(travel[k - 1] + f * (travel[k] - travel[k - 1]))


def table(results: dict[str, dict[int, dict[str, Any]]], policies: list[str], budgets: list[int]) -> str:
    heads = [f"{p} @{b}" for p in policies for b in budgets]
    lines = ["| plant | " + " | ".join(heads) + " |", "|---" * (len(heads) + 1) + "|"]
    means: dict[tuple[str, int], list[float]] = {}
    for plant, seeds in results.items():
        cells = []
        for name in policies:
            for b in budgets:
                share, of_means = shares(seeds, name, b)
                means.setdefault((name, b), []).append(float(share.mean()))
                cells.append(f"{share.mean():+.2f} ±{t_half(share):.2f} ({of_means:+.2f})")
        lines.append(f"| {plant.replace('_', ' ')} | " + " | ".join(cells) + " |")
    summary = [f"{np.mean(v):+.2f}, {sum(x >= 0.7 for x in v)}/{len(v)} >= 0.70" for v in means.values()]
    lines.append("| mean, species at 0.70 | " + " | ".join(summary) + " |")
    return "\n".join(lines)


def travel_table(results: dict[str, dict[int, dict[str, Any]]], policies: list[str], budget: int) -> str:
    """Each policy's camera travel to random's coverage after ``budget`` views, as a share of
    random's travel then: mean over seeds ± half its 95% t interval (seeds that got there)."""
    lines = [f"| plant | {' | '.join(policies)} |", "|---" * (len(policies) + 1) + "|"]
    pooled: dict[str, list[float]] = {p: [] for p in policies}
    for plant, seeds in results.items():
        cells = []
        for name in policies:
            ratios = []
            for s in seeds.values():
                target = s["random"]["coverage"][budget - 1]
                ratios.append(travel_to(s[name], target) / s["random"]["travel_m"][budget - 1])
            r = np.array(ratios)
            got = r[np.isfinite(r)]
            pooled[name] += list(got)
            cells.append(f"{got.mean():.2f} ±{t_half(got):.2f} ({len(got)}/{len(r)})" if len(got) else "never")
        lines.append(f"| {plant.replace('_', ' ')} | " + " | ".join(cells) + " |")
    cells = [f"{np.mean(v):.2f} ±{t_half(np.array(v)):.2f} ({len(v)})" if v else "never" for v in pooled.values()]
    lines.append("| all | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plant", nargs="+", default=["hydrangea"])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--budgets", default="5,10")
    parser.add_argument("--policies", default="spread")
    parser.add_argument("--resolution", default="480x270")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--cache", type=Path, help="read (and keep) the looks in this folder")
    args = parser.parse_args()
    budgets = sorted(int(b) for b in args.budgets.split(","))
    policies = [p for p in args.policies.split(",") if p not in ("random", "oracle")]
    plants = list(SPECIES) if args.plant == ["all"] else args.plant
    results: dict[str, dict[int, dict[str, Any]]] = {}
    for plant in plants:
        for seed in range(args.seeds):
            names, views = ["random", "oracle", *policies], max(budgets)
            if args.cache:
                results.setdefault(plant, {})[seed] = replay_cached(
                    args.cache, plant, seed, names, views, args.resolution
                )
            else:
                results.setdefault(plant, {})[seed] = replay(plant, seed, names, views, args.resolution)
            print(f"{plant} seed {seed} done", file=sys.stderr)
    if args.out:
        args.out.write_text(json.dumps({"budgets": budgets, "plants": results}))
    print(table(results, ["random", "oracle", *policies][2:], budgets))
    print()
    print(f"camera travel to random's coverage after {max(budgets)} views, of random's:")
    print(travel_table(results, ["oracle", *policies], max(budgets)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
