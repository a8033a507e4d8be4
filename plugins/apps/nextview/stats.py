"""``agrisim nextview``'s statistics over seeds: each policy's mean coverage at each budget with a
95% t interval, its difference to ``random`` paired by seed (the same plant, the same start),
the share of the oracle's gap to random it closes, and what it costs to reach random's coverage
at the largest budget: views, the arms' motion and the policy's own time deciding.

Every number is computed from the episodes' per-view records alone, so ``--report`` can draw
them again from any ``nextview.json``, an old single-seed one included. One seed gives a mean
but no interval: ``low`` and ``high`` are then None, never made up.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

#: the intervals' confidence
CONFIDENCE = 0.95
#: the policies the paired statistics are against
RANDOM, ORACLE = "random", "oracle"
#: an oracle no better than random by at most this share of the surface leaves no gap to close:
#: that seed's share of the gap is undefined (counted in ``undefined``), not a division by ~0
NO_GAP = 1e-9


class Episode(Protocol):
    """What the statistics read of an episode (:class:`agrisim.plugins.apps.nextview.study.PolicyRun`)."""

    plant: str
    policy: str
    seed: int | None
    coverage: list[float]
    motion_s: list[float]
    decision_s: list[float]
    setup_s: float | None

    def views_to(self, target: float) -> int | None: ...


@dataclass(frozen=True)
class Interval:
    """A mean over ``n`` values and its two-sided t interval (``low``, ``high``: None with
    fewer than two values; ``mean`` None with none)."""

    mean: float | None
    low: float | None
    high: float | None
    n: int

    @property
    def half(self) -> float | None:
        """Half the interval's width (None without an interval)."""
        return None if self.low is None or self.high is None else (self.high - self.low) / 2

    def as_dict(self) -> dict[str, Any]:
        return {"mean": self.mean, "low": self.low, "high": self.high, "n": self.n}


def t_interval(values: Sequence[float], confidence: float = CONFIDENCE) -> Interval:
    """The mean of ``values`` and Student's t interval around it (the sample standard deviation,
    ``n - 1`` degrees of freedom). Equal values give a zero-width interval."""
    from scipy import stats

    x = np.asarray(values, np.float64)
    n = len(x)
    if n == 0:
        return Interval(None, None, None, 0)
    mean = float(x.mean())
    if n == 1:
        return Interval(mean, None, None, 1)
    half = float(stats.t.ppf(0.5 + confidence / 2, n - 1)) * float(x.std(ddof=1)) / np.sqrt(n)
    return Interval(mean, mean - half, mean + half, n)


def coverage_at(episode: Episode, views: int) -> float | None:
    """The coverage after ``views`` views (None: the episode ended before)."""
    return episode.coverage[views - 1] if len(episode.coverage) >= views else None


def by_seed(episodes: Sequence[Episode]) -> dict[str, dict[str, dict[int | None, Episode]]]:
    """``{plant: {policy: {seed: episode}}}`` in the order the episodes come."""
    out: dict[str, dict[str, dict[int | None, Episode]]] = {}
    for e in episodes:
        out.setdefault(e.plant, {}).setdefault(e.policy, {})[e.seed] = e
    return out


def budget_statistics(
    runs: dict[int | None, Episode], random: dict[int | None, Episode], oracle: dict[int | None, Episode], views: int
) -> dict[str, Any]:
    """A policy's statistics at one budget (``views``), each from the seeds that have it:

    - ``coverage``: its mean coverage and t interval;
    - ``minus_random``: the mean of its per-seed difference to random and the t interval of
      those paired differences;
    - ``gap_share``: ``(policy - random) / (oracle - random)`` per seed, averaged, with its t
      interval; a seed whose oracle gains less than :data:`NO_GAP` over random is left out and
      counted in ``undefined`` (all of them: the mean is None, "n/a");
    - ``gap_share_of_means``: the same ratio of the means over those seeds (steadier where some
      seed's gap is tiny).
    """
    own = {s: c for s, e in runs.items() if (c := coverage_at(e, views)) is not None}
    paired = {s: (c, r) for s, c in own.items() if s in random and (r := coverage_at(random[s], views)) is not None}
    shares, undefined, triples = [], 0, []
    for s, (c, r) in paired.items():
        o = coverage_at(oracle[s], views) if s in oracle else None
        if o is None:
            continue
        if o - r <= NO_GAP:
            undefined += 1
            continue
        shares.append((c - r) / (o - r))
        triples.append((c, r, o))
    of_means = None
    if triples:
        c_m, r_m, o_m = np.mean(triples, axis=0)
        of_means = float((c_m - r_m) / (o_m - r_m)) if o_m - r_m > NO_GAP else None
    return {
        "coverage": t_interval(list(own.values())).as_dict(),
        "minus_random": t_interval([c - r for c, r in paired.values()]).as_dict(),
        "gap_share": {**t_interval(shares).as_dict(), "undefined": undefined},
        "gap_share_of_means": of_means,
    }


def to_random_coverage(
    runs: dict[int | None, Episode], random: dict[int | None, Episode], budget: int
) -> dict[str, Any]:
    """What a policy takes to see what random has seen after ``budget`` views, seed by seed:
    the views and the arms' motion time until its coverage first reaches random's; that motion
    over random's own until random first reached it (``motion_ratio``: under 1 is less motion at
    equal coverage); the motion saved (random's less its own), and its time deciding until then
    less random's (``extra_decision_s``). Means and t intervals over the seeds where it reaches
    it (``reached`` of ``seeds``)."""
    views, motion, ratio, saved, extra = [], [], [], [], []
    seeds = [s for s in runs if s in random and random[s].coverage]
    for s in seeds:
        ref, e = random[s], runs[s]
        target = ref.coverage[min(budget, len(ref.coverage)) - 1]
        k_ref, k = ref.views_to(target), e.views_to(target)
        if k is None or k_ref is None:
            continue
        m_ref, m = ref.motion_s[k_ref - 1], e.motion_s[k - 1]
        views.append(float(k))
        motion.append(m)
        saved.append(m_ref - m)
        if m_ref > 0:
            ratio.append(m / m_ref)
        if len(e.decision_s) >= k and len(ref.decision_s) >= k_ref:
            extra.append(float(sum(e.decision_s[:k]) - sum(ref.decision_s[:k_ref])))
    return {
        "budget": budget,
        "seeds": len(seeds),
        "reached": len(views),
        "views": t_interval(views).as_dict(),
        "motion_s": t_interval(motion).as_dict(),
        "motion_ratio": t_interval(ratio).as_dict(),
        "motion_saved_s": t_interval(saved).as_dict(),
        "extra_decision_s": t_interval(extra).as_dict(),
    }


def _duration(seconds: float) -> str:
    return f"{1000 * seconds:.0f} ms" if abs(seconds) < 1 else f"{seconds:.1f} s"


def verdict(to_random: dict[str, Any], policy: str) -> str | None:
    """Whether the time a policy spends deciding, beyond random's, outweighs the motion it saves
    against random at random's coverage (None: random itself, or no decision times recorded)."""
    if policy == RANDOM:
        return None
    if not to_random["reached"]:
        return "does not reach random's coverage"
    extra, saved = to_random["extra_decision_s"]["mean"], to_random["motion_saved_s"]["mean"]
    if extra is None:
        return None
    deciding = f"{_duration(extra)} more deciding" if extra >= 0 else f"{_duration(-extra)} less deciding"
    if saved <= 0:
        return f"saves no motion ({_duration(-saved)} more); {deciding}"
    if extra > saved:
        return f"**slower than the motion it saves**: {deciding} for {_duration(saved)} of motion saved"
    return f"{deciding} for {_duration(saved)} of motion saved"


def summarize(episodes: Sequence[Episode], budgets: Sequence[int]) -> dict[str, dict[str, dict[str, Any]]]:
    """``{plant: {policy: statistics}}`` (JSON-ready): ``seeds`` (how many), ``budgets`` (each
    budget's :func:`budget_statistics`), ``to_random`` (:func:`to_random_coverage` at the
    largest budget), the mean ``decision_s_per_view`` and ``motion_s_per_view`` over the seeds
    (each seed's mean over its views), ``setup_s`` (the policy's reset, once an episode) and
    ``verdict`` (:func:`verdict`)."""
    top = max(budgets)
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for plant, policies in by_seed(episodes).items():
        random, oracle = policies.get(RANDOM, {}), policies.get(ORACLE, {})
        for policy, runs in policies.items():
            reach = to_random_coverage(runs, random, top)
            decisions = [float(np.mean(e.decision_s)) for e in runs.values() if e.decision_s]
            moves = [e.motion_s[-1] / len(e.motion_s) for e in runs.values() if e.motion_s]
            setups = [e.setup_s for e in runs.values() if e.setup_s is not None]
            out.setdefault(plant, {})[policy] = {
                "seeds": len(runs),
                "budgets": {str(b): budget_statistics(runs, random, oracle, b) for b in budgets},
                "to_random": reach,
                "decision_s_per_view": t_interval(decisions).as_dict(),
                "motion_s_per_view": t_interval(moves).as_dict(),
                "setup_s": t_interval(setups).as_dict(),
                "verdict": verdict(reach, policy),
            }
    return out


# ------------------------------------------------------------------------------ the tables


def _pm(interval: dict[str, Any], digits: int = 3) -> str:
    """``mean ±half`` (the mean alone without an interval, "-" without a mean)."""
    mean, low, high = interval["mean"], interval["low"], interval["high"]
    if mean is None:
        return "-"
    if low is None or high is None:
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} ±{(high - low) / 2:.{digits}f}"


def _seeds_cell(n: int) -> str:
    return "n=1, no interval" if n == 1 else f"n={n}"


def coverage_table(stats: dict[str, dict[str, dict[str, Any]]], budgets: Sequence[int]) -> str:
    """A Markdown row a plant and policy, a column a budget: the mean coverage ±half its 95%
    interval, the share of the oracle's gap to random closed, and an arrow where the paired
    difference to random is above (↑) or below (↓) zero with 95% confidence."""
    lines = [
        "| plant | policy | seeds | " + " | ".join(f"@{b} views: coverage, gap share" for b in budgets) + " |",
        "|---" * (len(budgets) + 3) + "|",
    ]
    for plant, policies in stats.items():
        for policy, s in policies.items():
            cells = []
            for b in budgets:
                at = s["budgets"].get(str(b))
                if at is None or at["coverage"]["mean"] is None:
                    cells.append("-")
                    continue
                cell = _pm(at["coverage"])
                gap = at["gap_share"]
                if policy not in (RANDOM, ORACLE) and gap["mean"] is not None:
                    cell += f", gap {gap['mean']:.2f}"
                elif policy not in (RANDOM, ORACLE) and gap["undefined"]:
                    cell += ", gap n/a"
                if policy != RANDOM:
                    low, high = at["minus_random"]["low"], at["minus_random"]["high"]
                    cell += "↑" if low is not None and low > 0 else "↓" if high is not None and high < 0 else ""
                cells.append(cell)
            lines.append(
                f"| {plant.replace('_', ' ')} | {policy} | {_seeds_cell(s['seeds'])} | " + " | ".join(cells) + " |"
            )
    return "\n".join(lines)


def cost_table(stats: dict[str, dict[str, dict[str, Any]]], budget: int) -> str:
    """A Markdown row a plant and policy: the views and the arms' motion it takes to reach
    random's coverage after ``budget`` views (means over the seeds that reach it, how many of
    them), that motion against random's, the policy's time deciding a view beside the arms'
    motion a view, and whether the deciding outweighs the motion saved."""
    lines = [
        f"| plant | policy | views to random's @{budget} coverage (seeds) | motion then, s (of random's) "
        "| deciding a view, ms | motion a view, s | deciding against motion saved |",
        "|---|---|---|---|---|---|---|",
    ]
    for plant, policies in stats.items():
        for policy, s in policies.items():
            r = s["to_random"]
            if r["reached"]:
                views = f"{_pm(r['views'], 1)} ({r['reached']}/{r['seeds']})"
                motion = f"{_pm(r['motion_s'], 0)} ({_pm(r['motion_ratio'], 2)})"
            else:
                views = f"not reached (0/{r['seeds']})" if r["seeds"] else "- (no random)"
                motion = "-"
            d = s["decision_s_per_view"]
            decide = "-" if d["mean"] is None else f"{1000 * d['mean']:.1f}"
            move = _pm(s["motion_s_per_view"], 2)
            lines.append(
                f"| {plant.replace('_', ' ')} | {policy} | {views} | {motion} | {decide} | {move} | {s['verdict'] or '-'} |"
            )
    return "\n".join(lines)
