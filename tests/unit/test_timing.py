"""Ruckig time-parametrisation: limits respected, motion stays on the checked segments."""

from __future__ import annotations

import numpy as np

from agrisim.robot.trajectory import Limits, time_parametrize


def _path() -> np.ndarray:
    return np.array(
        [
            [0.0, -1.5, 1.5, -1.5, -1.5, 0.0],
            [0.8, -1.2, 1.0, -1.0, -1.2, 0.5],
            [0.9, -1.2, 1.0, -1.0, -1.2, 0.5],  # a short segment
            [-0.4, -1.8, 2.1, -2.0, -1.0, -0.6],
        ]
    )


def test_limits_are_respected():
    limits = Limits(np.array([2.16, 2.16, 3.15, 3.2, 3.2, 3.2]) * 0.5, np.full(6, 4.0), np.full(6, 40.0))
    timed = time_parametrize(_path(), limits)
    ts = np.linspace(0.0, timed.duration, 4001)
    q, qd, qdd = (np.array(x) for x in zip(*(timed.sample(float(t)) for t in ts), strict=True))
    eps = 1e-6
    assert np.all(np.abs(qd) <= limits.velocity + eps)
    assert np.all(np.abs(qdd) <= limits.acceleration + eps)
    # jerk from finite differences of Ruckig's accelerations (piecewise constant jerk)
    jerk = np.diff(qdd, axis=0) / np.diff(ts)[:, None]
    assert np.all(np.abs(jerk) <= limits.jerk * (1 + 1e-3) + 1e-3)
    # velocities are the derivative of positions (Ruckig's outputs are consistent)
    np.testing.assert_allclose(np.diff(q, axis=0) / np.diff(ts)[:, None], (qd[1:] + qd[:-1]) / 2, atol=2e-3)


def test_motion_stays_on_the_straight_segments_and_rests_at_waypoints():
    path = _path()
    limits = Limits(np.full(6, 2.0), np.full(6, 4.0), np.full(6, 40.0))
    timed = time_parametrize(path, limits)
    # at each boundary the arm is at the waypoint, at rest
    for k, t in enumerate(timed.boundaries):
        q, qd, _ = timed.sample(float(t))
        np.testing.assert_allclose(q, path[k], atol=1e-9)
        np.testing.assert_allclose(qd, 0.0, atol=1e-9)
    # in between, every sample lies on its segment (phase synchronisation)
    for k, (a, b) in enumerate(zip(path[:-1], path[1:], strict=True)):
        t0, t1 = timed.boundaries[k], timed.boundaries[k + 1]
        for t in np.linspace(t0, t1, 50):
            q = timed.sample(float(t))[0]
            s = np.dot(q - a, b - a) / np.dot(b - a, b - a)
            assert -1e-9 <= s <= 1 + 1e-9
            np.testing.assert_allclose(q, a + s * (b - a), atol=1e-9)


def test_discretize_samples_the_whole_trajectory():
    timed = time_parametrize(_path(), Limits(np.full(6, 2.0), np.full(6, 4.0), np.full(6, 40.0)))
    traj = timed.discretize(1 / 240)
    assert traj.t[0] == 0.0 and abs(traj.t[-1] - timed.duration) < 1e-12
    assert np.all(np.diff(traj.t) <= 1 / 240 + 1e-12)
    np.testing.assert_allclose(traj.q[-1], _path()[-1], atol=1e-9)
