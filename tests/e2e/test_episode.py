"""Whole episodes: setpoints reached within tolerance, no collisions (checked by a second
collision library), both arms moving together, run.json telling what happened."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agrisim.config import CellConfig, build_config
from agrisim.episode import Episode
from agrisim.plugins.physics.kinematic import KinematicOptions
from agrisim.plugins.physics.kinematic.backend import KinematicPhysics
from agrisim.plugins.rigs.paper.cell import build_cell
from agrisim.registry import hookimpl
from agrisim.scene.transforms import pose_error


class Recorder:
    """A test plugin on the event hooks."""

    def __init__(self) -> None:
        self.trajectories: list = []
        self.captures: list = []
        self.events: list[str] = []

    @hookimpl
    def agrisim_run_started(self, run):
        self.events.append("started")

    @hookimpl
    def agrisim_trajectory(self, run, robot, trajectory):
        self.trajectories.append(trajectory)

    @hookimpl
    def agrisim_capture(self, run, capture):
        self.captures.append(capture)

    @hookimpl
    def agrisim_run_finished(self, run, summary):
        self.events.append(f"finished:{summary.status}")


def _run(tmp_path, **overrides):
    layer = {
        "routine": {"setpoints": "2x3"},
        "renderer": {"backend": "none"},
        "output": {"out": str(tmp_path / "run"), "no_rrd": True},
    }
    for key, value in overrides.items():
        layer.setdefault(key, {}).update(value) if isinstance(value, dict) else layer.__setitem__(key, value)
    episode = Episode(build_config(layer))
    recorder = Recorder()
    episode.pm.register(recorder)
    run, summary = episode.run()
    return episode, run, summary, recorder


@pytest.fixture(scope="module")
def pybullet_run(tmp_path_factory):
    # 1x3: neighbouring columns are 85 degrees apart, and every seed tried (41 of 41) reaches
    # them without a search; a 2x3 routine needs an OMPL search that fails for about one seed
    # in twenty, which would make this fixture hinge on the IK branch a machine happens to find.
    return _run(tmp_path_factory.mktemp("ep"), routine={"setpoints": "1x3"})


def test_pybullet_episode_reaches_every_setpoint_within_tolerance(pybullet_run):
    episode, run, summary, recorder = pybullet_run
    assert summary.status == "complete" and summary.setpoints == 6
    assert summary.reached == 6, [r.reason for r in run.results if not r.reached]
    for r in run.results:
        assert r.ee_error_mm <= 0.05
    # captures carry the camera pose FK gives for the executed joints, at the setpoint
    targets = {sp.frame: sp.world_T_camera for sps in run.setpoints.values() for sp in sps}
    assert len(recorder.captures) == 6
    for cap in recorder.captures:
        assert pose_error(cap.world_T_camera, targets[cap.frame])[0] <= 5e-5
    assert recorder.events == ["started", "finished:complete"]


def test_executed_trajectories_are_collision_free_by_coal(pybullet_run):
    """Replay what pybullet says the arms did, both arms at the same instants, through
    Pinocchio + coal collision checking: no contact anywhere."""
    episode, run, summary, recorder = pybullet_run
    coal = KinematicPhysics(run.cell, KinematicOptions())
    try:
        # the arms' executed joint paths over the whole run, as functions of time
        by_robot: dict[str, list] = {}
        for tr in recorder.trajectories:
            by_robot.setdefault(tr.robot, []).append(tr.executed)
        samples = {
            r: (np.concatenate([e.t for e in ex]), np.concatenate([e.q for e in ex])) for r, ex in by_robot.items()
        }
        homes = {a.name: np.array(a.home) for a in run.cell.arms}

        def q_at(robot, t):
            ts, qs = samples[robot]
            i = np.searchsorted(ts, t, side="right") - 1
            return homes[robot] if i < 0 else qs[i]

        checked = 0
        for robot, (ts, qs) in samples.items():
            other = next(r for r in samples if r != robot)
            for t, q in zip(ts[::4], qs[::4], strict=True):
                assert not coal.in_collision(robot, q, {other: q_at(other, t)}), (robot, t)
                checked += 1
        assert checked > 100
    finally:
        coal.close()


def _reach_bound(physics: KinematicPhysics, robot: str) -> tuple[np.ndarray, float]:
    """The arm's first joint in the world, and a bound on how far any of its collision geometry
    can be from it in any configuration: the joint offsets along the chain plus each body's
    bounding sphere. Exact geometry, no sampling: a premise that cannot depend on the machine."""
    model, geom = physics.model, physics.geom
    root, bound = None, 0.0
    for obj in geom.geometryObjects:
        joint, chain = obj.parentJoint, 0.0
        if joint == 0 or not model.names[joint].startswith(f"{robot}/"):
            continue
        while model.parents[joint] != 0:
            chain += float(np.linalg.norm(model.jointPlacements[joint].translation))
            joint = model.parents[joint]
        root = joint
        obj.geometry.computeLocalAABB()
        centre = obj.placement.translation + obj.placement.rotation @ obj.geometry.aabb_center
        bound = max(bound, chain + float(np.linalg.norm(centre)) + float(obj.geometry.aabb_radius))
    assert root is not None, robot
    return model.jointPlacements[root].translation.copy(), bound


def _spans(recorder: Recorder) -> dict[tuple[str, int], tuple[float, float]]:
    return {(tr.robot, tr.setpoint): (tr.executed.t[0], tr.executed.t[-1]) for tr in recorder.trajectories}


FAR_APART = {"arm_distance": 2.5}  # arms 5 m apart: more than twice their reach


def _far_apart_routine(tmp_path) -> str:
    """Three camera poses per arm, looking down 0.8-1.0 m in front of its own base, with
    nothing between base and camera: every IK branch has a free straight line to them."""
    csv = tmp_path / "far.csv"
    rows = [(1.9, 0.3, 1.3), (1.8, -0.3, 1.2), (1.7, 0.0, 1.4)]
    csv.write_text(
        "robot,x,y,z,roll,pitch,yaw\n"
        + "".join(
            f"{robot},{sign * x},{y},{z},3.14159,0,0\n" for robot, sign in (("r1", 1), ("r2", -1)) for x, y, z in rows
        )
    )
    return str(csv)


@pytest.mark.parametrize("physics", ["kinematic", "pybullet"])
def test_arms_move_together_when_their_workspaces_cannot_meet(tmp_path, physics):
    """Arms 5 m apart, each photographing in front of itself: whatever IK branch or path is
    found, the arms cannot touch, so every step moves both at once and nobody waits."""
    csv = _far_apart_routine(tmp_path)
    cell = FAR_APART
    coal = KinematicPhysics(build_cell(CellConfig(**cell)), KinematicOptions())
    (o1, reach1), (o2, reach2) = _reach_bound(coal, "r1"), _reach_bound(coal, "r2")
    assert reach1 + reach2 < np.linalg.norm(o1 - o2) - 1.0  # a metre to spare, not a graze

    episode, run, summary, recorder = _run(
        tmp_path, physics={"backend": physics}, planner={"backend": "ompl"}, routine={"csv": csv}, cell=cell
    )
    assert summary.reached == 6, [r.reason for r in run.results if not r.reached]
    spans = _spans(recorder)
    assert all(spans["r1", k][0] == spans["r2", k][0] for k in range(3)), spans
    assert not any(r.waited for r in run.results)


@pytest.mark.parametrize("physics", ["kinematic", "pybullet"])
def test_an_arm_waits_when_moving_together_would_collide(tmp_path, physics):
    """Both cameras sent to the same point at the same step: moving together certainly ends in
    a collision, so r1 goes first and r2 waits, then finds every solution blocked by r1."""
    csv = tmp_path / "sp.csv"
    csv.write_text("robot,x,y,z,roll,pitch,yaw\nr1,0.0,0.0,1.4,3.14159,0,0\nr2,0.0,0.0,1.4,3.14159,0,3.14159\n")
    episode, run, summary, recorder = _run(
        tmp_path, physics={"backend": physics}, planner={"backend": "ompl"}, routine={"csv": str(csv)}
    )
    by_robot = {r.robot: r for r in run.results}
    assert by_robot["r1"].reached and not by_robot["r1"].waited
    assert by_robot["r2"].waited and not by_robot["r2"].reached
    assert "collision" in by_robot["r2"].reason
    assert ("r2", 0) not in _spans(recorder)  # r2 never moved towards r1


def test_run_json_records_the_run(pybullet_run):
    episode, run, summary, recorder = pybullet_run
    doc = json.loads((run.out_dir / "run.json").read_text())
    assert doc["status"] == "complete"
    assert doc["config"]["routine"]["setpoints"] == "1x3"
    assert doc["backends"] == {"physics": "pybullet", "planner": "ompl"}
    assert doc["backend_options"]["physics"]["rate"] >= 240
    assert {"pin", "pybullet", "ompl", "ruckig", "rerun-sdk"} <= set(doc["versions"])
    assert len(doc["results"]) == 6 and all(r["reached"] for r in doc["results"])
    assert doc["summary"]["reached"] == 6 and set(doc["summary"]["wall_s"]) >= {"ik", "plan", "execute"}
    cams = json.loads((run.out_dir / "cameras.json").read_text())
    assert len(cams["frames"]) == 6
    np.testing.assert_allclose(np.array(cams["intrinsics"]["K"])[0, 2], 960.0)


def test_arms_take_turns_when_moving_together_would_collide(tmp_path, monkeypatch):
    """When the joint check says the simultaneous motions collide, one arm waits."""
    from agrisim.plugins.physics.kinematic.backend import KinematicPhysics as K

    monkeypatch.setattr(K, "arms_in_collision", lambda self, configs: True)
    episode, run, summary, recorder = _run(
        tmp_path, physics={"backend": "kinematic"}, planner={"backend": "ompl"}, routine={"setpoints": "1x3"}
    )
    assert summary.reached == 6
    spans = _spans(recorder)
    for k in range(3):
        assert spans["r2", k][0] >= spans["r1", k][1] - 1e-9  # r2 starts after r1 arrived
    assert all(r.waited for r in run.results if r.robot == "r2")


def test_unreachable_setpoints_are_recorded_and_the_run_goes_on(tmp_path):
    csv = tmp_path / "sp.csv"
    csv.write_text(
        "robot,x,y,z,roll,pitch,yaw\nr1,0.3,0,1.2,3.14159,0,0\nr1,4.0,0,1.0,0,0,0\nr1,0.3,0.1,1.2,3.14159,0,0\n"
    )
    episode, run, summary, recorder = _run(
        tmp_path, physics={"backend": "kinematic"}, cell={"arms": 1}, routine={"csv": str(csv)}
    )
    assert [r.reached for r in run.results] == [True, False, True]
    assert "ik: no solution" in run.results[1].reason
    assert summary.status == "complete" and summary.failed == 1


@pytest.mark.parametrize("physics, planner", [("kinematic", "ompl"), ("pybullet", "direct")])
def test_backends_swap(tmp_path, physics, planner):
    # The far-apart routine: with the straight-line planner, the hemisphere's outcome would
    # depend on the IK branch found (a line that grazes the plant on one machine, not another).
    episode, run, summary, recorder = _run(
        tmp_path,
        physics={"backend": physics},
        planner={"backend": planner},
        routine={"csv": _far_apart_routine(tmp_path)},
        cell=FAR_APART,
    )
    assert run.backends == {"physics": physics, "planner": planner}
    assert summary.reached == 6


def test_cell_matches_the_paper():
    cell = build_cell(CellConfig())
    for arm in cell.arms:
        base = arm.world_T_base[:3, 3]
        assert abs(abs(base[0]) - 1.0) < 1e-12 and base[2] == 0.95


def test_the_papers_routine_with_default_backends(tmp_path):
    """The default run (pybullet physics, OMPL, 2 x 50 setpoints): at least 95 reached, each
    within 0.05 mm, and pybullet saw no contact along any executed trajectory."""
    episode = Episode(
        build_config({"renderer": {"backend": "none"}, "output": {"out": str(tmp_path / "run"), "no_rrd": True}})
    )
    run, summary = episode.run()
    assert summary.setpoints == 100
    assert summary.reached >= 95, [(r.frame, r.reason) for r in run.results if not r.reached]
    assert all(r.ee_error_mm <= 0.05 for r in run.results if r.reached)
    assert summary.collisions == 0 and not any(r.contacts for r in run.results)


def test_a_rendered_run_needs_no_open3d(tmp_path) -> None:
    """``agrisim run --physics kinematic --recon none`` (the raycast renderer, the Rerun
    recording) where ``import open3d`` fails, as on a minimal install: the run completes, writes
    its views, and Open3D is never asked for."""
    import subprocess
    import sys

    from conftest import isolated_env

    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(
        "import sys\n"
        "class NoOpen3D:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] == 'open3d':\n"
        "            raise ImportError('no Open3D here')\n"
        "sys.meta_path.insert(0, NoOpen3D())\n"
    )
    out = tmp_path / "run"
    args = ["run", "--physics", "kinematic", "--recon", "none", "--setpoints", "1x1", "--resolution", "96x54"]
    code = "import sys; from agrisim.app.cli import main; sys.exit(main())"
    env = isolated_env(PYTHONPATH=str(site), AGRISIM_CACHE_DIR=str(tmp_path / "cache"))
    done = subprocess.run(
        [sys.executable, "-c", code, *args, "--out", str(out)], env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    run = json.loads((out / "run.json").read_text())
    assert run["status"] == "complete" and len(run["frames_complete"]) == 2
    probe = subprocess.run([sys.executable, "-c", "import open3d"], env=env, capture_output=True, text=True)
    assert probe.returncode != 0 and "no Open3D here" in probe.stderr  # the block held
