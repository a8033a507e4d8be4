"""``agrisim nextview``: the view-choosing benchmark. Each plant, each policy
(:mod:`agrisim.plugins.apps.nextview.policies`) runs one episode of ``agrisim/PlantView-v0``; every step's
coverage and motion time go to ``OUT/nextview.json``, each episode's views to its own run
directory (``OUT/<plant>/<policy>/episode_0000``), the curves to ``OUT/nextview.png``, and a
table says how many views and how much motion each policy needs to see what the paper's 100
views see."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import OutputError, UserError

#: the paper's policy always takes every candidate: its final coverage is the others' target
PAPER = "paper"


@dataclass
class PolicyRun:
    """One policy's episode on one plant: after each step, the coverage and the motion so far."""

    plant: str
    policy: str
    coverage: list[float] = field(default_factory=list)
    motion_s: list[float] = field(default_factory=list)
    reach_failures: int = 0
    run_dir: str = ""

    def views_to(self, target: float) -> int | None:
        """The views after which the coverage first reaches ``target`` (None: never)."""
        hit = np.flatnonzero(np.asarray(self.coverage) >= target - 1e-12)
        return int(hit[0]) + 1 if len(hit) else None


def check_request(plants: Sequence[str], policies: Sequence[str], views: int) -> None:
    """Refuse an unknown policy or too few views (plants are checked when their env is built)."""
    from agrisim.plugins.apps.nextview.policies import POLICIES

    unknown = [p for p in policies if p not in POLICIES]
    if unknown:
        raise UserError(f"unknown policy {unknown[0]!r}; policies are {', '.join(POLICIES)}")
    if views < 1:
        raise UserError(f"--views must be 1 or more, got {views}")
    if not plants:
        raise UserError("--plant names no plant")


def reachable_candidates(env: Any) -> int:
    """How many of ``env``'s candidates an arm's IK reaches (collisions aside): a set none of
    them reaches is refused before any episode runs."""
    from agrisim.robot.kinematics import ArmKinematics
    from agrisim.validation import open_rig

    _, cell = open_rig(env.config)
    kins = {arm.name: (ArmKinematics(arm), np.array(arm.home)) for arm in cell.arms}
    rng = np.random.default_rng(0)
    count = 0
    for sp in env.candidates:
        kin, home = kins[sp.robot]
        count += kin.ik(sp.world_T_camera, home, rng=rng, restarts=4, max_restarts=16).q is not None
    return count


def check_candidates(plant: str, env_options: dict[str, Any]) -> None:
    """Refuse a candidate set that no arm reaches at all, before anything runs or is written."""
    from agrisim.plugins.apps.nextview.env import PlantViewEnv

    env = PlantViewEnv(plant=plant, **env_options)
    try:
        if not reachable_candidates(env):
            raise UserError(
                f"none of the {len(env.candidates)} candidate views is within the arms' reach "
                f"(routine radius {env.config.routine.radius} m): nothing to choose from"
            )
    finally:
        env.close()


def run_benchmark(
    plants: Sequence[str],
    policies: Sequence[str],
    views: int,
    out: Path,
    env_options: dict[str, Any],
    seed: int = 0,
    progress: Callable[[str, int, int], None] | None = None,
) -> list[PolicyRun]:
    """Every plant x policy episode (the paper's first on each plant: the others' target)."""
    from agrisim.plugins.apps.nextview.env import PlantViewEnv
    from agrisim.plugins.apps.nextview.policies import POLICIES

    order = [PAPER] + [p for p in policies if p != PAPER]
    episodes: list[PolicyRun] = []
    for plant in plants:
        for name in order:
            env = PlantViewEnv(plant=plant, out=out / _slug(plant) / name, **env_options)
            steps = len(env.candidates) if name == PAPER else min(views, len(env.candidates))
            env.max_views = steps
            policy = POLICIES[name](seed)
            obs, info = env.reset(seed=seed, options={"plant_seed": seed, "pcg_seed": 42})
            policy.reset(env)
            record = PolicyRun(plant, name)
            done = False
            while not done:
                action = policy.act(env, obs)
                obs, _, terminated, truncated, info = env.step(action)
                policy.observe(action, info)
                record.coverage.append(info["coverage"])
                record.motion_s.append(info["motion_total_s"])
                done = terminated or truncated
                if progress is not None:
                    progress(f"{plant} {name}", len(record.coverage), steps)
            record.reach_failures, record.run_dir = info["reach_failures"], info["run_dir"]
            env.close()
            episodes.append(record)
            _write(out, episodes)
    return episodes


def _slug(plant: str) -> str:
    return Path(plant).stem if plant.endswith((".glb", ".gltf", ".obj")) else plant


def _write(out: Path, episodes: list[PolicyRun]) -> None:
    from agrisim.files.atomic import write_json

    doc: dict[str, dict[str, Any]] = {}
    for e in episodes:
        doc.setdefault(e.plant, {})[e.policy] = {
            "coverage": e.coverage,
            "motion_s": e.motion_s,
            "reach_failures": e.reach_failures,
            "run_dir": e.run_dir,
        }
    write_json(
        out / "nextview.json", {"plants": doc, "coverage": "share of the true surface seen (both sides of leaves)"}
    )


#: the share of the paper's final coverage the table also asks each policy to reach
NEAR = 0.99


def table(episodes: list[PolicyRun]) -> str:
    """A Markdown row a plant and policy: coverage after 10 and 30 views; the views each policy
    takes to reach the paper's 100-view coverage, and 99% of it, with the arms' motion time
    then (and its share of the paper's whole routine); reach failures."""
    paper = {e.plant: e for e in episodes if e.policy == PAPER}
    lines = [
        "| plant | policy | coverage @10 / @30 views | views to the paper's coverage (motion, of the paper's) "
        f"| views to {100 * NEAR:.0f}% of it (motion, of the paper's) | reach failures |",
        "|---|---|---|---|---|---|",
    ]
    for e in episodes:
        ref = paper.get(e.plant)
        target = ref.coverage[-1] if ref is not None and ref.coverage else float("nan")
        at = [f"{e.coverage[n - 1]:.3f}" if len(e.coverage) >= n else "-" for n in (10, 30)]
        cells = []
        for goal in (target, NEAR * target):
            k = e.views_to(goal)
            if k is None:
                cells.append("not reached")
                continue
            motion = e.motion_s[k - 1]
            whole = ref.motion_s[-1] if ref is not None and ref.motion_s else 0.0
            cells.append(f"{k} ({motion:.0f} s, {100 * motion / whole:.0f}%)" if whole else f"{k} ({motion:.0f} s)")
        lines.append(
            f"| {e.plant.replace('_', ' ')} | {e.policy} | {' / '.join(at)} | {cells[0]} | {cells[1]} | {e.reach_failures} |"
        )
    return "\n".join(lines)


def pivot(episodes: list[PolicyRun]) -> str:
    """The same, a row a plant and a column a policy: coverage after the last view (30 by
    default) and, in brackets, the views to 99% of the paper policy's coverage after all its
    views (the rig's routine: 100 on the paper's cell)."""
    paper = {e.plant: e for e in episodes if e.policy == PAPER}
    policies = list(dict.fromkeys(e.policy for e in episodes if e.policy != PAPER))
    cell = {(e.plant, e.policy): e for e in episodes}
    n = max((len(e.coverage) for e in paper.values()), default=100)  # every candidate: the rig's routine
    lines = [f"| plant | paper, {n} views | " + " | ".join(policies) + " |", "|---" * (len(policies) + 2) + "|"]
    for plant, ref in paper.items():
        row = [f"{ref.coverage[-1]:.3f}" if ref.coverage else "-"]
        for name in policies:
            e = cell.get((plant, name))
            if e is None or not e.coverage:
                row.append("-")
                continue
            k = e.views_to(NEAR * ref.coverage[-1]) if ref.coverage else None
            row.append(f"{e.coverage[-1]:.3f} ({k if k is not None else '-'})")
        lines.append(f"| {plant.replace('_', ' ')} | " + " | ".join(row) + " |")
    return "\n".join(lines)


def read_episodes(path: Path) -> list[PolicyRun]:
    """The episodes of a nextview.json (to print its table again)."""
    import json

    doc = json.loads(path.read_text())["plants"]
    return [
        PolicyRun(plant, policy, e["coverage"], e["motion_s"], e["reach_failures"], e["run_dir"])
        for plant, policies in doc.items()
        for policy, e in policies.items()
    ]


def plot(episodes: list[PolicyRun], path: Path) -> None:
    """Coverage against views and against motion time, a row a plant."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plants = list(dict.fromkeys(e.plant for e in episodes))
    fig, axes = plt.subplots(len(plants), 2, figsize=(10, 2.4 * len(plants)), squeeze=False)
    for row, plant in zip(axes, plants, strict=True):
        for e in (e for e in episodes if e.plant == plant):
            views = np.arange(1, len(e.coverage) + 1)
            row[0].plot(views, e.coverage, label=e.policy)
            row[1].plot(e.motion_s, e.coverage, label=e.policy)
        row[0].set_title(f"{plant.replace('_', ' ')}: coverage against views", fontsize=9)
        row[1].set_title("against the arms' motion time", fontsize=9)
        row[0].set_xscale("log")
        row[0].set_xlabel("views")
        row[1].set_xlabel("motion, s")
        for ax in row:
            ax.set_ylabel("true surface seen")
            ax.grid(alpha=0.3)
        row[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def prepare_out(out: Path, overwrite: bool) -> None:
    """``out`` made ready: a finished benchmark there is kept unless ``overwrite``."""
    import shutil

    if (out / "nextview.json").exists() and not overwrite:
        raise OutputError(f"{out} holds a benchmark already (nextview.json); pass --overwrite to replace it")
    if out.exists() and overwrite:
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
