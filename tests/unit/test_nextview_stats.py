"""``agrisim nextview``'s statistics (agrisim.plugins.apps.nextview.stats) on hand-made episodes,
against scipy and numpy computed here another way: the t intervals of the mean and of the
paired differences to random, the share of the oracle's gap closed (a seed whose oracle is no
better than random left out, all of them: n/a), one seed giving no interval, the views and
motion to reach random's coverage, and a policy whose deciding outweighs the motion it saves
called out in the table."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats as sps

from agrisim.plugins.apps.nextview.stats import cost_table, coverage_table, summarize, t_interval
from agrisim.plugins.apps.nextview.study import PolicyRun

#: per seed, coverage after each of 4 views (random, oracle, a planner that on seed 2 never
#: reaches random's coverage after 4 views)
RANDOM = [[0.20, 0.40, 0.55, 0.60], [0.25, 0.35, 0.50, 0.62], [0.10, 0.30, 0.45, 0.58], [0.30, 0.45, 0.52, 0.66]]
ORACLE = [[0.35, 0.60, 0.70, 0.75], [0.30, 0.50, 0.65, 0.72], [0.25, 0.50, 0.62, 0.70], [0.40, 0.55, 0.65, 0.70]]
PLANNER = [[0.30, 0.50, 0.62, 0.66], [0.20, 0.45, 0.60, 0.64], [0.20, 0.40, 0.55, 0.57], [0.28, 0.52, 0.66, 0.69]]


def runs(policy: str, curves: list[list[float]], motion_a_view: float, decide_s: float) -> list[PolicyRun]:
    return [
        PolicyRun(
            "coltsfoot",
            policy,
            list(c),
            list(motion_a_view * (1 + seed + np.arange(len(c)))),  # each seed a little different
            seed=seed,
            decision_s=[decide_s] * len(c),
        )
        for seed, c in enumerate(curves)
    ]


def episodes(planner_decide_s: float = 0.01) -> list[PolicyRun]:
    return [
        *runs("random", RANDOM, 2.0, 1e-4),
        *runs("oracle", ORACLE, 2.0, 0.01),
        *runs("planner", PLANNER, 1.5, planner_decide_s),
    ]


def scipy_interval(x: np.ndarray) -> tuple[float, float]:
    """The 95% t interval of the mean of ``x``, as scipy's one-sample t test gives it."""
    ci = sps.ttest_1samp(x, 0.0).confidence_interval(0.95)
    return float(ci.low), float(ci.high)


@pytest.mark.parametrize("budget", [1, 2, 4])
def test_intervals_and_gap_share_match_scipy(budget: int) -> None:
    at = summarize(episodes(), [1, 2, 4])["coltsfoot"]["planner"]["budgets"][str(budget)]
    p, r, o = (np.array([c[budget - 1] for c in curves]) for curves in (PLANNER, RANDOM, ORACLE))
    assert at["coverage"]["n"] == 4 and at["coverage"]["mean"] == pytest.approx(p.mean())
    assert (at["coverage"]["low"], at["coverage"]["high"]) == pytest.approx(scipy_interval(p))
    paired = sps.ttest_rel(p, r).confidence_interval(0.95)
    assert at["minus_random"]["mean"] == pytest.approx((p - r).mean())
    assert (at["minus_random"]["low"], at["minus_random"]["high"]) == pytest.approx((paired.low, paired.high))
    share = (p - r) / (o - r)
    assert at["gap_share"]["mean"] == pytest.approx(share.mean()) and at["gap_share"]["undefined"] == 0
    assert (at["gap_share"]["low"], at["gap_share"]["high"]) == pytest.approx(scipy_interval(share))
    assert at["gap_share_of_means"] == pytest.approx((p.mean() - r.mean()) / (o.mean() - r.mean()))


def test_a_seed_whose_oracle_ties_random_has_no_gap_share() -> None:
    """Seed 1's oracle equals random after 1 view: its share is undefined, the other three's
    averaged; with every seed tied, n/a."""
    tied = [list(c) for c in ORACLE]
    tied[1][0] = RANDOM[1][0]
    eps = [*runs("random", RANDOM, 2.0, 0.0), *runs("oracle", tied, 2.0, 0.0), *runs("planner", PLANNER, 2.0, 0.0)]
    gap = summarize(eps, [1])["coltsfoot"]["planner"]["budgets"]["1"]["gap_share"]
    keep = [0, 2, 3]
    share = [(PLANNER[s][0] - RANDOM[s][0]) / (ORACLE[s][0] - RANDOM[s][0]) for s in keep]
    assert gap["undefined"] == 1 and gap["n"] == 3 and gap["mean"] == pytest.approx(np.mean(share))
    eps = [*runs("random", RANDOM, 2.0, 0.0), *runs("oracle", RANDOM, 2.0, 0.0), *runs("planner", PLANNER, 2.0, 0.0)]
    stats = summarize(eps, [1])
    gap = stats["coltsfoot"]["planner"]["budgets"]["1"]["gap_share"]
    assert gap["undefined"] == 4 and gap["mean"] is None
    assert "gap n/a" in coverage_table(stats, [1])


def test_one_seed_gives_a_mean_and_no_interval() -> None:
    one = [e for e in episodes() if e.seed == 0]
    stats = summarize(one, [2])
    at = stats["coltsfoot"]["planner"]["budgets"]["2"]
    assert at["coverage"] == {"mean": PLANNER[0][1], "low": None, "high": None, "n": 1}
    assert at["minus_random"]["low"] is None and at["gap_share"]["high"] is None
    row = next(line for line in coverage_table(stats, [2]).splitlines() if "| planner |" in line)
    assert "n=1, no interval" in row and "±" not in row and f"{PLANNER[0][1]:.3f}, gap" in row
    assert t_interval([]).mean is None and t_interval([0.5, 0.5, 0.5]).half == 0.0


def test_views_and_motion_to_randoms_coverage() -> None:
    """Random's coverage after its 4th view, seed by seed: the views at which each curve first
    reaches it, the motion then, and that motion over random's."""
    stats = summarize(episodes(), [4])["coltsfoot"]
    views, motion, ratio = [], [], []
    for seed, (c, ref) in enumerate(zip(PLANNER, RANDOM, strict=True)):
        target = ref[-1]
        k = int(np.argmax(np.array(c) >= target)) + 1 if max(c) >= target else None
        if k is None:
            continue
        views.append(k)
        motion.append(1.5 * (seed + k))
        ratio.append(1.5 * (seed + k) / (2.0 * (seed + 4)))
    reach = stats["planner"]["to_random"]
    assert reach["seeds"] == 4 and reach["reached"] == len(views) == 3
    assert reach["views"]["mean"] == pytest.approx(np.mean(views))
    assert reach["motion_s"]["mean"] == pytest.approx(np.mean(motion))
    assert reach["motion_ratio"]["mean"] == pytest.approx(np.mean(ratio))
    assert (reach["motion_ratio"]["low"], reach["motion_ratio"]["high"]) == pytest.approx(
        scipy_interval(np.array(ratio))
    )
    assert stats["random"]["to_random"]["motion_ratio"]["mean"] == pytest.approx(1.0)


def test_deciding_slower_than_the_motion_saved_is_said() -> None:
    """The planner saves motion against random at random's coverage; deciding 10 ms a view it
    is worth it, deciding 10 s a view it is slower than the motion it saves."""
    quick = summarize(episodes(0.01), [4])["coltsfoot"]["planner"]
    slow_stats = summarize(episodes(10.0), [4])
    slow = slow_stats["coltsfoot"]["planner"]
    saved = slow["to_random"]["motion_saved_s"]["mean"]
    assert saved > 0 and quick["to_random"]["motion_saved_s"]["mean"] == saved
    assert "slower" not in quick["verdict"] and "saved" in quick["verdict"]
    assert slow["verdict"].startswith("**slower than the motion it saves**")
    assert slow["decision_s_per_view"]["mean"] == pytest.approx(10.0)
    row = next(line for line in cost_table(slow_stats, 4).splitlines() if "| planner |" in line)
    assert "| 10000.0 |" in row and "**slower" in row
