"""The ``gantry`` rig: a Cartesian XYZ stage over the plant, a pan-tilt camera on its ram.

Truth: the hemisphere's geometry (each viewpoint ``look_at`` from its polar angle and azimuth
towards the aim point, written out here), Pinocchio's forward kinematics of the gantry's whole
URDF at the closed-form joints, the joints a camera position and heading imply (the stage at
the eye, the head panned to the azimuth's opposite and tilted down to the aim), and the axes'
speed limits (a move of d at speed v takes at least d / v).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from agrisim.config import RoutineConfig, RunConfig
from agrisim.files import layout
from agrisim.plugins.rigs.gantry.cell import GantryRig
from agrisim.plugins.rigs.gantry.urdf import viewpoint_joints
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.urdf import CAMERA_FRAME
from agrisim.scene.transforms import look_at
from agrisim.testing.contracts import check

SMALL = ["--resolution", "48x36", "--recon", "none", "--no-rrd", "--shadow-samples", "0", "--setpoints", "2x3"]
#: the run's speed limits, other than the defaults so that a test sees them reach the joints:
#: x, y, z in m/s, the head in degrees a second
SPEEDS = {
    "speed_x": 0.25,
    "speed_y": 0.3,
    "speed_z": 0.15,
    "pan_tilt_speed_deg_s": 60.0,
    "acceleration": 0.4,
    "pan_tilt_acceleration_deg_s2": 120.0,
}


def viewpoints(routine: RoutineConfig, centre: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """(eye, aim, azimuth) of each viewpoint in shooting order: L polar angles over ``phi_deg``
    from the top, C azimuths 360/C degrees apart from half a step, every other level backwards."""
    levels, columns = (int(v) for v in routine.setpoints.split("x"))
    aim = centre + np.array([0.0, 0.0, routine.aim_height])
    out = []
    for i, phi in enumerate(np.radians(np.linspace(*routine.phi_deg, levels))):
        azimuths = [(k + 0.5) * 2 * math.pi / columns for k in range(columns)]
        for a in azimuths if i % 2 == 0 else azimuths[::-1]:
            eye = centre + routine.radius * np.array(
                [math.sin(phi) * math.cos(a), math.sin(phi) * math.sin(a), math.cos(phi)]
            )
            out.append((eye, aim, a))
    return out


def test_the_rig_keeps_the_rig_contract() -> None:
    check("rig", "gantry", Registry(make_plugin_manager()))


@pytest.mark.parametrize(
    "routine",
    [
        RoutineConfig(),
        RoutineConfig(setpoints="3x4", phi_deg=(0.0, 80.0), radius=0.3, aim_height=0.1),
        RoutineConfig(setpoints="1x2", phi_deg=(80.0, 80.0), radius=0.6, aim_height=0.3),
    ],
    ids=["default-5x10", "zenith-to-low", "looking-up"],
)
def test_each_setpoint_is_its_hemisphere_viewpoint_by_closed_form_joints(routine: RoutineConfig) -> None:
    """Each setpoint is ``look_at`` from its viewpoint towards the aim to 1e-9; Pinocchio's FK
    of the whole URDF at the closed-form joints gives that pose; and the joints are what the
    viewpoint implies: the stage at the eye, the head panned to look back across the axis and
    tilted down towards the aim (straight down at the zenith, where look_at's image x is +x)."""
    rig = GantryRig(RunConfig().cell)
    cell = rig.cell()
    arm = cell.arms[0]
    model = pin.buildModelFromXML(arm.urdf)
    assert tuple(model.names[1:]) == arm.joints == ("x", "y", "z", "pan", "tilt")
    data, frame = model.createData(), model.getFrameId(CAMERA_FRAME)
    setpoints = rig.setpoints(cell, routine)[arm.name]
    expected = viewpoints(routine, cell.plant_center)
    assert [sp.index for sp in setpoints] == list(range(len(expected)))
    for sp, (eye, aim, azimuth) in zip(setpoints, expected, strict=True):
        view = look_at(eye, aim)
        np.testing.assert_allclose(sp.world_T_camera, view, atol=1e-9, rtol=0)
        q = viewpoint_joints(view, arm.world_T_base)
        pin.framesForwardKinematics(model, data, q)
        np.testing.assert_allclose(arm.world_T_base @ data.oMf[frame].homogeneous, view, atol=1e-9, rtol=0)
        np.testing.assert_allclose(q[:3], eye - arm.world_T_base[:3, 3], atol=1e-12)
        horizontal = math.hypot(eye[0] - aim[0], eye[1] - aim[1])
        if horizontal > 1e-9:
            back = math.remainder(q[3] - (azimuth + math.pi), 2 * math.pi)
            assert abs(back) < 1e-12 and math.isclose(q[4], math.atan2(eye[2] - aim[2], horizontal), abs_tol=1e-12)
        else:
            assert math.isclose(q[3], math.pi / 2) and math.isclose(q[4], math.pi / 2)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2 x 3 hemisphere on the kinematic backend, at the speeds of :data:`SPEEDS`."""
    from agrisim.app.cli import main

    out = tmp_path_factory.mktemp("gantry") / "run"
    speeds = [a for k, v in SPEEDS.items() for a in ("--set", f"rig.gantry.{k}={v}")]
    code = main(["run", "--rig", "gantry", "--physics", "kinematic", *speeds, *SMALL, "--out", str(out)])
    assert code == 0
    return out


def test_a_run_reaches_every_viewpoint_of_the_hemisphere(run: Path) -> None:
    doc = json.loads((run / layout.RUN_JSON).read_text())
    assert doc["config"]["rig"]["backend"] == "gantry"
    assert [(r["frame"], r["reached"]) for r in doc["results"]] == [(f"g1_{k:03d}", True) for k in range(6)]
    frames = json.loads((run / layout.CAMERAS_JSON).read_text())["frames"]
    routine = RoutineConfig(setpoints="2x3")
    for k, (eye, aim, _) in enumerate(viewpoints(routine, np.array([0.0, 0.0, RunConfig().cell.table_height]))):
        shot = np.asarray(frames[f"g1_{k:03d}"]["world_T_camera"])
        np.testing.assert_allclose(shot, look_at(eye, aim), atol=1e-6)


def test_every_move_keeps_within_the_axes_speed_limits(run: Path) -> None:
    """Every sample of every planned move keeps each joint within its speed (its velocity and
    its steps between samples) and its acceleration (the gantry's own, below [motion]'s), a move
    takes at least its longest axis's distance over that axis's speed, and some move runs an
    axis at its speed and one at its acceleration (the limits bind, not slower ones)."""
    limits = np.array([SPEEDS["speed_x"], SPEEDS["speed_y"], SPEEDS["speed_z"], *[math.radians(60.0)] * 2])
    accelerations = np.array([SPEEDS["acceleration"]] * 3 + [math.radians(120.0)] * 2)
    fastest, hardest = np.zeros(5), np.zeros(5)
    moves = sorted((run / layout.TRAJECTORIES).glob("g1_*.json"))
    assert len(moves) == 6
    for path in moves:
        doc = json.loads(path.read_text())
        assert doc["joints"] == ["x", "y", "z", "pan", "tilt"]
        t, q, qd = (np.asarray(doc["planned"][k], float) for k in ("t", "q", "qd"))
        assert (np.abs(qd) <= limits * (1 + 1e-6)).all(), (path.name, np.abs(qd).max(axis=0), limits)
        steps = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
        assert (steps <= limits * (1 + 1e-3)).all(), (path.name, steps.max(axis=0))
        assert t[-1] - t[0] >= (np.abs(q[-1] - q[0]) / limits).max() - 1e-9, path.name
        fastest = np.maximum(fastest, np.abs(qd).max(axis=0))
        qdd = np.abs(np.diff(qd, axis=0)) / np.diff(t)[:, None]
        assert (qdd <= accelerations * (1 + 1e-6)).all(), (path.name, qdd.max(axis=0), accelerations)
        hardest = np.maximum(hardest, qdd.max(axis=0))
    assert (fastest / limits).max() > 0.95, fastest / limits
    assert (hardest / accelerations).max() > 0.95, hardest / accelerations


def test_a_run_on_pybullet_reaches_every_viewpoint(tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "run"
    code, stdout, err = cli(["run", "--rig", "gantry", "--physics", "pybullet", *SMALL, "--out", str(out)])
    assert code == 0, err
    assert sum(line.startswith("rig: gantry g1: travel 1.2 x 1.2 m") for line in stdout.splitlines()) == 1
    results = json.loads((out / layout.RUN_JSON).read_text())["results"]
    assert [r["frame"] for r in results if r["reached"]] == [f"g1_{k:03d}" for k in range(6)], results
    assert not any(r["contacts"] for r in results)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--set", "routine.radius=0.9"], "set rig.gantry.travel_x >= 1.76 and rig.gantry.travel_y >= 1.52, or"),
        (["--set", "rig.gantry.travel_y=0.8"], "needs y = -0.422 m from the plant's axis, beyond +-0.400 m"),
        (["--set", "rig.gantry.z_min=1.0"], "below the ram's lowest (rig.gantry.z_min = 1)"),
        (["--set", "rig.gantry.beam_height=1.2"], "above the ram's highest (1.060 m under rails"),
        (["--set", "rig.gantry.z_min=1.7"], "z_min 1.7 m leaves the ram no stroke"),
        (["--set", "rig.gantry.speed_z=0"], "speed_z"),
        (["--set", "rig.gantry.travel=2"], "travel"),
    ],
    ids=["radius", "travel-y", "z-min", "beam", "no-stroke", "speed", "unknown"],
)
def test_bad_input_is_refused_in_one_line(args: list[str], says: str, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "never"
    code, _, err = cli(["run", "--rig", "gantry", *args, "--physics", "kinematic", *SMALL, "--out", str(out)])
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert "Traceback" not in err and not out.exists()
