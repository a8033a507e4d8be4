"""Robot-side timings: IK, collision queries, planning, Ruckig, and the full robot-only
episode of the paper (100 setpoints, pybullet physics, OMPL). Prints figures; asserts nothing.

    python bench/robot_episode.py            # everything (about a minute)
    python bench/robot_episode.py --quick    # skip the full episodes
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from agrisim.config import CellConfig, build_config
from agrisim.episode import Episode
from agrisim.plugins.physics.kinematic import KinematicOptions
from agrisim.plugins.physics.kinematic.backend import KinematicPhysics
from agrisim.plugins.physics.pybullet_physics import BulletOptions
from agrisim.plugins.physics.pybullet_physics.backend import BulletPhysics
from agrisim.plugins.planners.ompl_planner import OmplOptions
from agrisim.plugins.planners.ompl_planner.backend import OmplPlanner
from agrisim.plugins.rigs.paper.cell import build_cell
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.setpoints import random_views
from agrisim.robot.trajectory import Limits, time_parametrize

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402


def per_call(fn, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n


def bench_components() -> None:
    cell = build_cell(CellConfig())
    k = ArmKinematics(cell.arms[0])
    rng = np.random.default_rng(0)
    home = np.array(cell.arms[0].home)
    targets = random_views(cell.plant_center, rng)
    q_warm = [k.ik(T, home, rng=rng).q for T in targets]
    t_cold = per_call(lambda: k._solve(k._base.actInv(__import__("pinocchio").SE3(targets[0])), home, 200, 1e-7), 50)
    t_warm = per_call(lambda: k.ik(k.fk(q_warm[1] + 0.01), q_warm[1], rng=rng), 200)
    print(
        f"IK (damped least squares, Pinocchio): one cold solve {t_cold * 1e3:.2f} ms; warm, near the current joints {t_warm * 1e3:.2f} ms"
    )

    bullet = BulletPhysics(cell, BulletOptions())
    coal = KinematicPhysics(cell, KinematicOptions())
    qs = rng.uniform(k.lower / 2, k.upper / 2, (2000, 6))
    for name, ph in (("pybullet (5 mm clearance)", bullet), ("kinematic (coal)", coal)):
        it = iter(qs)
        t = per_call(lambda ph=ph, it=it: ph.in_collision("r1", next(it)), 2000)
        print(f"collision query, {name}: {1 / t:,.0f} per s")

    limits = Limits(k.velocity_limit, np.full(6, 4.0), np.full(6, 40.0))
    t_ruckig = per_call(lambda: time_parametrize(np.array([home, home + 0.7]), limits), 2000)
    print(f"Ruckig, one 6-DoF rest-to-rest segment: {t_ruckig * 1e6:.1f} us")

    start = np.array([-0.756, -0.852, 1.986, -2.546, -0.372, -1.741])
    goal = np.array([0.331, -0.675, 1.895, -3.537, -2.631, 0.756])
    planner = OmplPlanner(OmplOptions())
    valid = lambda q: not bullet.in_collision("r1", q)  # noqa: E731
    times = []
    for seed in range(5):
        t0 = time.perf_counter()
        path = planner.plan(start, goal, valid, k.lower, k.upper, seed, 0.02)
        times.append(time.perf_counter() - t0)
    print(
        f"OMPL RRTConnect around the plant (straight line blocked), simplified and re-checked: "
        f"median {np.median(times) * 1e3:.0f} ms over 5 plans, {len(path)} waypoints"
    )
    bullet.close()
    coal.close()


def bench_episode(physics: str, planner: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        cfg = build_config(
            {
                "physics": {"backend": physics},
                "planner": {"backend": planner},
                "renderer": {"backend": "none"},
                "output": {"out": str(Path(tmp) / "run"), "no_rrd": True},
            }
        )
        t0 = time.perf_counter()
        episode = Episode(cfg)
        run, summary = episode.run()
        wall = time.perf_counter() - t0
    worst = max(r.ee_error_mm for r in run.results if r.reached)
    stages = ", ".join(f"{k} {v:.2f}" for k, v in summary.wall_s.items())
    print(
        f"episode {physics:9s} + {planner:6s}: {wall:5.1f} s wall for {summary.setpoints} setpoints; "
        f"reached {summary.reached}, collisions {summary.collisions}, worst error {worst:.4f} mm, "
        f"simulated {summary.sim_time:.1f} s  [{stages}]"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="components only")
    args = parser.parse_args()
    print(cpu_model())
    bench_components()
    if not args.quick:
        for physics, planner in (("pybullet", "ompl"), ("pybullet", "direct"), ("kinematic", "ompl")):
            bench_episode(physics, planner)


if __name__ == "__main__":
    main()
