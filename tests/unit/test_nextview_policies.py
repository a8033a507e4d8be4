"""``agrisim nextview``'s spread policies (agrisim.plugins.apps.nextview.policies) on a hand-made
ring of candidates, against answers computed here another way: the aim point their axes meet;
farthest-point sampling's every step the largest smallest angle (angles by atan2), its first view
the nearest, and its set within Gonzalez's factor 2 of the brute-force best spread; the cover's
every step the most orientations added (counted by angle) and its set within 1 - 1/e of the
brute-force best cover; a view out of reach counted as unseen; the same choices twice."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
import pytest

from agrisim.plugins.apps.nextview.policies import (
    POLICIES,
    Spread,
    SpreadMaximin,
    orientations,
    view_directions,
)
from agrisim.robot.setpoints import Setpoint
from agrisim.scene.transforms import look_at

AIM = np.array([0.1, -0.2, 1.1])


def ring(levels: tuple[float, ...] = (50.0, 75.0, 100.0), columns: int = 6) -> list[Setpoint]:
    """Cameras at polar angles ``levels`` (degrees from the zenith) x ``columns`` azimuths,
    0.4 m from :data:`AIM`, looking at it; two arms, each its half of the azimuths."""
    out = []
    for polar in np.radians(levels):
        for c in range(columns):
            azimuth = 2 * np.pi * c / columns + 0.3 * polar  # levels staggered: no exact ties
            d = np.array([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
            arm = "r1" if c < columns // 2 else "r2"
            out.append(Setpoint(arm, len(out), look_at(AIM + 0.4 * d, AIM)))
    return out


@dataclass
class FakeEnv:
    """What the spread policies read of a PlantViewEnv: the candidates and where each arm's
    camera is (moved to a view when it is taken)."""

    candidates: list[Setpoint]
    cameras: dict[str, np.ndarray] = field(default_factory=dict)

    def camera_position(self, robot: str) -> np.ndarray:
        return self.cameras[robot]


def angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b)))


def sees_by_angle(directions: np.ndarray) -> np.ndarray:
    """Which orientations each view sees (views x sphere): those within the cone, by atan2 of
    the cross and dot products, not the policy's thresholded dot products."""
    sphere = orientations()
    cross = np.linalg.norm(np.cross(directions[:, None, :], sphere[None, :, :]), axis=2)
    return np.arctan2(cross, directions @ sphere.T) <= np.radians(Spread.CONE_DEG) + 1e-12


def episode(policy_name: str, env: FakeEnv, views: int, unreachable: frozenset[int] = frozenset()) -> list[int]:
    policy = POLICIES[policy_name](0)
    policy.reset(env)  # type: ignore[arg-type]
    chosen = []
    for _ in range(views):
        i = policy.act(env, {})  # type: ignore[arg-type]
        reached = i not in unreachable
        if reached:
            env.cameras[env.candidates[i].robot] = env.candidates[i].world_T_camera[:3, 3]
        policy.observe(i, {"reached": reached})
        chosen.append(i)
    return chosen


def fresh() -> FakeEnv:
    return FakeEnv(ring(), {"r1": AIM + np.array([0.5, 0.3, 0.4]), "r2": AIM + np.array([-0.5, -0.3, 0.4])})


def test_directions_are_about_the_point_the_cameras_aim_at() -> None:
    env = fresh()
    eyes = np.array([sp.world_T_camera[:3, 3] for sp in env.candidates])
    expected = (eyes - AIM) / np.linalg.norm(eyes - AIM, axis=1, keepdims=True)
    assert view_directions(env) == pytest.approx(expected, abs=1e-9)  # type: ignore[arg-type]


def test_maximin_is_farthest_point_sampling() -> None:
    env = fresh()
    start = dict(env.cameras)
    d = view_directions(env)  # type: ignore[arg-type]
    chosen = episode("spread-maximin", env, 6)
    assert len(set(chosen)) == 6
    # the first: the candidate nearest its arm's camera
    travel = [np.linalg.norm(sp.world_T_camera[:3, 3] - start[sp.robot]) for sp in env.candidates]
    assert chosen[0] == int(np.argmin(travel))
    for k in range(1, 6):  # each next: the largest smallest angle to those before (ties within 0.02 rad)
        spread = {i: min(angle(d[i], d[j]) for j in chosen[:k]) for i in range(len(d)) if i not in chosen[:k]}
        assert spread[chosen[k]] >= max(spread.values()) - SpreadMaximin.TIE_RAD
    # Gonzalez: greedy's smallest pairwise angle is at least half the best over every 4-set
    between = np.array([[angle(a, b) for b in d] for a in d])

    def separation(views: tuple[int, ...]) -> float:
        return min(between[a, b] for a, b in itertools.combinations(views, 2))

    best = max(separation(s) for s in itertools.combinations(range(len(d)), 4))
    assert separation(tuple(chosen[:4])) >= best / 2 - 1e-12


def test_spread_covers_the_most_orientations_each_view() -> None:
    env = fresh()
    d = view_directions(env)  # type: ignore[arg-type]
    sees = sees_by_angle(d)
    chosen = episode("spread", env, 4)
    covered = np.zeros(sees.shape[1], bool)
    for i in chosen:
        added = {j: int((sees[j] & ~covered).sum()) for j in range(len(d)) if j not in chosen[: chosen.index(i)]}
        assert added[i] == max(added.values())
        covered |= sees[i]
    best = max(int(np.any(sees[list(s)], axis=0).sum()) for s in itertools.combinations(range(len(d)), 3))
    cover3 = int(np.any(sees[chosen[:3]], axis=0).sum())
    assert cover3 >= (1 - 1 / np.e) * best
    assert cover3 >= 0.95 * best  # greedy is near the best here


def test_a_view_out_of_reach_counts_as_unseen_and_choices_repeat() -> None:
    first = episode("spread", fresh(), 5)
    assert episode("spread", fresh(), 5) == first  # deterministic: the same plant, the same views
    # the third view is out of reach: the fourth adds the most to what the first two saw (on
    # this ring another view than the one a seen third leads to)
    env = fresh()
    missed = episode("spread", env, 4, unreachable=frozenset({first[2]}))
    assert missed[:3] == first[:3]
    sees = sees_by_angle(view_directions(env))  # type: ignore[arg-type]
    covered = sees[first[0]] | sees[first[1]]
    added = {j: int((sees[j] & ~covered).sum()) for j in range(len(sees)) if j not in first[:3]}
    assert added[missed[3]] == max(added.values()) and missed[3] != first[3]
