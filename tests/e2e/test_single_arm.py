"""The ``single-arm`` rig: one arm of example-robot-data's (``--robot``) or a user's URDF
(``--robot-urdf`` + ``--camera-link``) beside the plant. Its URDF loader against the paper's
(byte for byte), IK of every built-in arm against Pinocchio's forward kinematics, whole runs on
both physics backends, a hand-written URDF, and the refusals of bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from agrisim.config import RunConfig
from agrisim.files import layout
from agrisim.plugins.rigs.single_arm import SingleArmOptions
from agrisim.plugins.rigs.single_arm.cell import SingleArmRig
from agrisim.plugins.rigs.single_arm.robots import ROBOTS
from agrisim.plugins.rigs.single_arm.urdf_camera import with_camera
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.cell import Arm
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.urdf import CAMERA_FRAME, ur10_urdf_path, ur10_with_camera
from agrisim.testing.contracts import check

BOX_ARM = Path(__file__).resolve().parents[1] / "data" / "box_arm.urdf"
SMALL = ["--resolution", "96x54", "--setpoints", "2x3", "--recon", "none", "--no-rrd", "--shadow-samples", "0"]
#: the built-in arms that can set a camera pose (so101 has five joints)
ARMS = [name for name in ROBOTS if name != "so101"]


def test_the_generic_loader_gives_the_paper_rigs_ur10_byte_for_byte() -> None:
    ur10 = ROBOTS["ur10"]
    desc = with_camera(ur10_urdf_path(), ur10.mount, ur10.xyz, ur10.rpy, relative_meshes=False)
    assert desc.urdf == ur10_with_camera()
    assert desc.joints == Arm("r1", "", np.eye(4), "").joints  # the paper's six UR10 joints


@pytest.mark.parametrize("robot", ARMS)
def test_ik_reaches_what_forward_kinematics_says_the_arm_reaches(robot: str) -> None:
    """Joints drawn within limits, their camera pose from Pinocchio's FK of the whole URDF
    (gripper joints at zero): IK from a random start puts the camera there."""
    spec = ROBOTS[robot]
    desc = with_camera(spec.path(), spec.mount, spec.xyz, spec.rpy)
    model = pin.buildModelFromXML(desc.urdf)  # the full model, not the reduced one IK uses
    data = model.createData()
    frame = model.getFrameId(CAMERA_FRAME, pin.FrameType.BODY)
    kin = ArmKinematics(Arm("r1", desc.urdf, np.eye(4), "", joints=desc.joints, home=(0.0,) * len(desc.joints)))
    assert kin.dof == len(desc.joints) == model.nq
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.uniform(kin.lower, kin.upper)
        pin.framesForwardKinematics(model, data, q)
        target = data.oMf[frame].homogeneous
        found = kin.ik(target, rng.uniform(kin.lower, kin.upper), rng=rng, restarts=8, max_restarts=60)
        assert found.ok, f"{robot}: {found.reason}"
        reached = kin.fk(found.q)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 5e-5
        assert np.linalg.norm(pin.log3(reached[:3, :3].T @ target[:3, :3])) < 1e-4


def test_the_rig_keeps_the_rig_contract() -> None:
    check("rig", "single-arm", Registry(make_plugin_manager()))


def _reached(out: Path) -> tuple[int, int]:
    results = json.loads((out / layout.RUN_JSON).read_text())["results"]
    return sum(r["reached"] for r in results), len(results)


@pytest.mark.parametrize(
    ("robot", "physics", "grid"),
    [("xarm7", "kinematic", "2x3"), ("ur5", "kinematic", "2x3"), ("panda", "pybullet", "5x10")],
)
def test_a_run_with_a_built_in_arm_reaches_its_setpoints(
    robot: str, physics: str, grid: str, tmp_path: Path, cli
) -> None:  # noqa: ANN001
    """The Panda on the default routine's 50 viewpoints under pybullet's dynamics: its long hand
    behind the camera, low beside the table (the table ends inside the lowest ring), at joint
    limits (a start a hair beyond one), and its wrist's motors resting short of their targets
    under gravity (the hold is trimmed). 49-50 of 50 reached over seeds 1-3."""
    out = tmp_path / "run"
    small = [*SMALL[:2], "--setpoints", grid, *SMALL[4:]]
    code, stdout, err = cli(["run", "--robot", robot, "--physics", physics, *small, "--out", str(out)])
    assert code == 0, err
    assert sum(line.startswith(f"rig: {robot} on the single-arm rig") for line in stdout.splitlines()) == 1
    reached, total = _reached(out)
    levels, columns = (int(n) for n in grid.split("x"))
    assert total == levels * columns and reached >= 0.95 * total
    run = json.loads((out / layout.RUN_JSON).read_text())
    assert run["config"]["rig"] == {"backend": "single-arm", "single-arm": {"robot": robot}}
    links = json.loads(next((out / layout.LINK_POSES).glob("r1_*.json")).read_text())
    assert set(links) == {"r1"} and CAMERA_FRAME in links["r1"]


def test_a_users_urdf_runs(tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "run"
    code, stdout, err = cli(
        ["run", "--robot-urdf", str(BOX_ARM), "--camera-link", "tool", "--physics", "kinematic"]
        + [*SMALL, "--out", str(out)]
    )
    assert code == 0, err
    assert "box_arm.urdf on the single-arm rig (6 joints" in stdout
    reached, total = _reached(out)
    assert total == 6 and reached == 6  # (4 before the table ended inside the lowest ring)


@pytest.mark.parametrize("robot", ["xarm7", "ur5"])
def test_a_computed_home_is_free_of_collisions(robot: str) -> None:
    """Free for coal's exact meshes, and its links as far apart as at the arm's zero joints,
    less HOME_SELF_SLACK (a UR5's first home had its forearm and wrist 10 mm apart, 15 at zero:
    within pybullet's 5 mm clearance of their convex hulls, and no setpoint was planned). The
    xArm7's is free for pybullet too; the UR5's layout and home differ with the machine's
    floating point (under the AVX2 emulation its home is within pybullet's clearance again)."""
    from agrisim.plugins.physics.kinematic.backend import KinematicPhysics
    from agrisim.plugins.physics.pybullet_physics import BulletOptions
    from agrisim.plugins.physics.pybullet_physics.backend import BulletPhysics
    from agrisim.plugins.rigs.single_arm.layout import HOME_SELF_SLACK

    cell = SingleArmRig(RunConfig().cell, SingleArmOptions(robot=robot)).cell()
    arm = cell.arms[0]
    home = np.asarray(arm.home)
    kinematic = KinematicPhysics(cell)
    assert kinematic.collisions(q={arm.name: home}) == []
    zero = np.clip(np.zeros(len(home)), *(ArmKinematics(arm).lower, ArmKinematics(arm).upper))
    assert kinematic.self_distance(arm.name, home) >= kinematic.self_distance(arm.name, zero) - HOME_SELF_SLACK
    if robot == "xarm7":
        bullet = BulletPhysics(cell, BulletOptions())
        try:
            assert not bullet.in_collision(arm.name, home)
        finally:
            bullet.close()


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--robot", "atlas"], "unknown robot 'atlas'; robots: ur3, ur5, ur10, panda"),
        (["--robot", "so101"], "so101 has 5 joints"),
        (["--robot-urdf", "{bad}", "--camera-link", "tool"], "cannot read URDF"),
        (["--robot-urdf", str(BOX_ARM), "--camera-link", "hand"], "has no link 'hand'"),
        (["--camera-link", "tool"], "--camera-link goes with --robot-urdf"),
        (["--robot-urdf", str(BOX_ARM)], "--robot-urdf needs --camera-link"),
        (["--robot", "panda", "--rig", "paper"], "--robot chooses the single-arm rig, not --rig paper"),
        (
            ["--robot", "ur3", "--set", "rig.single-arm.distance=2.5", "--set", "rig.single-arm.radius=0.3"],
            "reaches about",
        ),
    ],
    ids=["unknown", "five-joints", "unparsable", "no-link", "link-alone", "urdf-alone", "other-rig", "too-far"],
)
def test_bad_input_is_refused_in_one_line(args: list[str], says: str, tmp_path: Path, cli) -> None:  # noqa: ANN001
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    out = tmp_path / "never"
    code, _, err = cli(
        ["run", *[a.replace("{bad}", str(bad)) for a in args], "--physics", "kinematic", *SMALL, "--out", str(out)]
    )
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert "Traceback" not in err and not out.exists()
