"""``agrisim nextview``: the view-choosing benchmark. Each seed, each plant, each policy
(:mod:`agrisim.plugins.apps.nextview.policies`) runs one episode of ``agrisim/PlantView-v0``, the
seed the plant's and the episode's, so that every policy of a seed starts from the same plant and
the same place; every step's coverage, motion time and the policy's time deciding go to
``OUT/nextview.json``, each episode's views to its own run directory
(``OUT/<plant>/<policy>/episode_0000``, one a seed in turn), the curves to ``OUT/nextview.png``.
The tables (:mod:`agrisim.plugins.apps.nextview.stats`) give each policy's mean coverage at each
budget with a 95% interval over the seeds, paired against random, the share of the oracle's gap
it closes, and what it takes to reach random's coverage; then, for the first seed, how many views
and how much motion each policy needs to see what the paper's 100 views see."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import OutputError, UserError

#: the paper's policy always takes every candidate: its final coverage is the others' target
PAPER = "paper"
#: the views the tables report at when neither ``--budgets`` nor ``--views`` is given
DEFAULT_BUDGETS = (5, 10, 20, 30)


@dataclass
class PolicyRun:
    """One policy's episode on one plant: after each step, the coverage and the motion so far,
    and the seconds the policy took to choose that step's view (``decision_s``, the step's own,
    not a running total; empty in a benchmark from before it was measured). ``setup_s``: the
    policy's reset (the oracle's look from every candidate); ``map_s``: the environment's
    upkeep of its voxel map over the episode, done whatever the policy. ``seed``: None in a
    benchmark from before seeds were recorded."""

    plant: str
    policy: str
    coverage: list[float] = field(default_factory=list)
    motion_s: list[float] = field(default_factory=list)
    reach_failures: int = 0
    run_dir: str = ""
    seed: int | None = None
    decision_s: list[float] = field(default_factory=list)
    setup_s: float | None = None
    map_s: float | None = None

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


def resolve_budgets(views: int | None, budgets: str | None) -> list[int]:
    """The budgets, ascending: ``--budgets`` ("5,10,20,30"), or ``--views N`` as the one budget
    N, or :data:`DEFAULT_BUDGETS`; both given, or a budget not a whole number of 1 or more, is
    refused."""
    if views is not None and budgets is not None:
        raise UserError("--views and --budgets both given: --views N is the one budget N; give one of them")
    if budgets is None:
        if views is not None and views < 1:
            raise UserError(f"--views must be 1 or more, got {views}")
        return [views] if views is not None else list(DEFAULT_BUDGETS)
    parts = [p.strip() for p in budgets.split(",")]
    if not all(p.isdigit() and int(p) >= 1 for p in parts):
        raise UserError(
            f"--budgets takes views, whole numbers of 1 or more separated by commas (e.g. 5,10,20,30), got {budgets!r}"
        )
    return sorted({int(p) for p in parts})


def resolve_seeds(seed: int | None, seeds: int | None) -> list[int]:
    """The seeds: ``--seeds N`` the seeds 0 to N-1, ``--seed S`` the one seed S, else seed 0;
    both given, or a count under 1 or a negative seed, is refused."""
    if seed is not None and seeds is not None:
        raise UserError(
            "--seed and --seeds both given: --seed S runs the one seed S, --seeds N the seeds 0 to N-1; give one of them"
        )
    if seeds is not None:
        if seeds < 1:
            raise UserError(f"--seeds must be 1 or more (the seeds 0 to N-1), got {seeds}")
        return list(range(seeds))
    if seed is not None and seed < 0:
        raise UserError(f"--seed must be 0 or more, got {seed}")
    return [0 if seed is None else seed]


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
    *,
    seeds: Sequence[int] | None = None,
    budgets: Sequence[int] | None = None,
) -> list[PolicyRun]:
    """Every seed x plant x policy episode of ``views`` views (the paper's first on each plant:
    the others' target; it takes every candidate). ``seeds`` (else the one ``seed``): each the
    plant's seed, the episode's and the policy's. ``budgets`` (else ``[views]``): the views the
    statistics written to ``nextview.json`` after each episode report at. A whole seed comes
    before the next, so a benchmark cut short holds complete pairs."""
    from agrisim.plugins.apps.nextview.env import PlantViewEnv
    from agrisim.plugins.apps.nextview.policies import POLICIES

    seeds = list(seeds) if seeds is not None else [seed]
    budgets = list(budgets) if budgets is not None else [views]
    order = [PAPER] + [p for p in policies if p != PAPER]
    episodes: list[PolicyRun] = []
    for s in seeds:
        for plant in plants:
            for name in order:
                env = PlantViewEnv(plant=plant, out=out / _slug(plant) / name, **env_options)
                steps = len(env.candidates) if name == PAPER else min(views, len(env.candidates))
                env.max_views = steps
                policy = POLICIES[name](s)
                obs, info = env.reset(seed=s, options={"plant_seed": s, "pcg_seed": 42})
                t0 = time.perf_counter()
                policy.reset(env)
                record = PolicyRun(plant, name, seed=s, setup_s=time.perf_counter() - t0)
                label = f"{plant} {name}" + (f" seed {s}" if len(seeds) > 1 else "")
                done = False
                while not done:
                    # the policy's own time: its choice, not the move, render or map that follow
                    t0 = time.perf_counter()
                    action = policy.act(env, obs)
                    record.decision_s.append(time.perf_counter() - t0)
                    obs, _, terminated, truncated, info = env.step(action)
                    policy.observe(action, info)
                    record.coverage.append(info["coverage"])
                    record.motion_s.append(info["motion_total_s"])
                    done = terminated or truncated
                    if progress is not None:
                        progress(label, len(record.coverage), steps)
                record.reach_failures, record.run_dir = info["reach_failures"], info["run_dir"]
                record.map_s = env.timing["map"]
                env.close()
                episodes.append(record)
                _write(out, episodes, seeds, budgets)
    return episodes


def _slug(plant: str) -> str:
    return Path(plant).stem if plant.endswith((".glb", ".gltf", ".obj")) else plant


#: nextview.json's layout: 2 added ``episodes``, ``seeds``, ``budgets`` and ``statistics``
FORMAT = 2


def _episode_doc(e: PolicyRun) -> dict[str, Any]:
    return {
        "coverage": e.coverage,
        "motion_s": e.motion_s,
        "reach_failures": e.reach_failures,
        "run_dir": e.run_dir,
        "seed": e.seed,
        "decision_s": e.decision_s,
        "setup_s": e.setup_s,
        "map_s": e.map_s,
    }


def _write(out: Path, episodes: list[PolicyRun], seeds: Sequence[int], budgets: Sequence[int]) -> None:
    """``plants``: the first seed's episodes, as before seeds (what older readers read);
    ``episodes``: every seed's; ``statistics``: :func:`agrisim.plugins.apps.nextview.stats.summarize`."""
    from agrisim.files.atomic import write_json
    from agrisim.plugins.apps.nextview.stats import CONFIDENCE, summarize

    doc: dict[str, dict[str, Any]] = {}
    for e in episodes:
        if e.seed == seeds[0]:
            doc.setdefault(e.plant, {})[e.policy] = _episode_doc(e)
    write_json(
        out / "nextview.json",
        {
            "plants": doc,
            "coverage": "share of the true surface seen (both sides of leaves)",
            "format": FORMAT,
            "seeds": list(seeds),
            "budgets": list(budgets),
            "episodes": [{"plant": e.plant, "policy": e.policy, **_episode_doc(e)} for e in episodes],
            "statistics": summarize(episodes, budgets),
            "intervals": f"{100 * CONFIDENCE:.0f}% Student t over seeds; minus_random and gap_share paired by seed",
        },
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
    """The episodes of a nextview.json (to print its table again): every seed's, or in a
    benchmark from before seeds, the one episode a plant and policy (its seed None)."""
    return read_benchmark(path)[0]


def read_benchmark(path: Path) -> tuple[list[PolicyRun], list[int]]:
    """A nextview.json's episodes and the budgets it reports at (one from before budgets: the
    :data:`DEFAULT_BUDGETS` its episodes reach, and their length)."""
    import json

    doc = json.loads(path.read_text())

    def run(plant: str, policy: str, e: dict[str, Any]) -> PolicyRun:
        return PolicyRun(
            plant,
            policy,
            e["coverage"],
            e["motion_s"],
            e["reach_failures"],
            e["run_dir"],
            e.get("seed"),
            e.get("decision_s", []),
            e.get("setup_s"),
            e.get("map_s"),
        )

    if "episodes" in doc:
        episodes = [run(e["plant"], e["policy"], e) for e in doc["episodes"]]
    else:
        episodes = [
            run(plant, policy, e) for plant, policies in doc["plants"].items() for policy, e in policies.items()
        ]
    budgets = doc.get("budgets")
    if not budgets:
        chosen = [len(e.coverage) for e in episodes if e.policy != PAPER] or [len(e.coverage) for e in episodes]
        views = max(chosen, default=max(DEFAULT_BUDGETS))
        budgets = sorted({b for b in DEFAULT_BUDGETS if b < views} | {views})
    return episodes, [int(b) for b in budgets]


def report(episodes: list[PolicyRun], budgets: Sequence[int]) -> str:
    """What the command prints: the statistics over seeds (coverage at each budget, then what
    reaching random's coverage costs), then for the first seed the tables against the paper's
    views (:func:`table`, :func:`pivot`)."""
    from agrisim.plugins.apps.nextview.stats import cost_table, coverage_table, summarize

    stats = summarize(episodes, budgets)
    seeds = list(dict.fromkeys(e.seed for e in episodes))
    first = [e for e in episodes if e.seed == seeds[0]] if seeds else []
    legend = (
        "coverage: the mean over seeds ±half its 95% t interval; gap: (policy - random) / (oracle - random), "
        "each seed's, averaged (n/a: the oracle no better than random); ↑ ↓: above or below random, "
        "paired by seed, with 95% confidence"
    )
    heading = f"seed {seeds[0]} alone, against the paper's views:\n\n" if len(seeds) > 1 else ""
    return "\n\n".join(
        [
            coverage_table(stats, budgets) + "\n\n" + legend,
            cost_table(stats, max(budgets)),
            heading + table(first) + "\n\n" + pivot(first),
        ]
    )


def plot(episodes: list[PolicyRun], path: Path, budgets: Sequence[int] = ()) -> None:
    """A row a plant: coverage against views, each policy's mean over the seeds and its 95%
    band (no band with one seed), the budgets marked; and the mean coverage against the mean
    motion time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agrisim.plugins.apps.nextview.stats import by_seed, t_interval

    grouped = by_seed(episodes)
    fig, axes = plt.subplots(len(grouped), 2, figsize=(10, 2.4 * len(grouped)), squeeze=False)
    for row, (plant, policies) in zip(axes, grouped.items(), strict=True):
        for name, runs in policies.items():
            length = max(len(e.coverage) for e in runs.values())
            steps = [t_interval([e.coverage[k] for e in runs.values() if len(e.coverage) > k]) for k in range(length)]
            mean = np.array([i.mean for i in steps], np.float64)
            views = np.arange(1, length + 1)
            (line,) = row[0].plot(views, mean, label=name if len(runs) == 1 else f"{name} (n={len(runs)})")
            low = np.array([np.nan if i.low is None else i.low for i in steps])
            high = np.array([np.nan if i.high is None else i.high for i in steps])
            if np.isfinite(low).any():
                row[0].fill_between(views, low, high, color=line.get_color(), alpha=0.2, linewidth=0)
            motion = [np.mean([e.motion_s[k] for e in runs.values() if len(e.motion_s) > k]) for k in range(length)]
            row[1].plot(motion, mean, label=name, color=line.get_color())
        for b in budgets:
            row[0].axvline(b, color="0.6", linewidth=0.6, linestyle=":")
        row[0].set_title(f"{plant.replace('_', ' ')}: coverage against views (mean, 95% band)", fontsize=9)
        row[1].set_title("against the arms' motion time (means)", fontsize=9)
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
