"""The ``turntable`` rig: the plant on a turning stage, cameras fixed on a column. Simulated in
the stage's frame (the cameras orbit the plant by minus the stage's angle).

Truth: rotations about the stage's axis (each camera's poses are its first pose turned by minus
the stage's angle), the stage's speed limit (a move of a quarter turn cannot take less than a
quarter turn at top speed), and the plant itself turned in front of a camera that stays put
(the turntable as built in a lab): its labels pixel for pixel and its depth within rounding.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from agrisim.config import RunConfig
from agrisim.files import layout
from agrisim.plugins.rigs.turntable import TurntableOptions
from agrisim.plugins.rigs.turntable.cell import TurntableRig
from agrisim.registry import Registry, make_plugin_manager
from agrisim.testing.contracts import check

SMALL = ["--resolution", "96x54", "--recon", "none", "--no-rrd", "--shadow-samples", "0", "--physics", "kinematic"]


def turn_z(angle: float, centre: np.ndarray) -> np.ndarray:
    """A turn by ``angle`` about the vertical axis through ``centre``, 4 x 4."""
    c, s = math.cos(angle), math.sin(angle)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = centre - T[:3, :3] @ centre
    return T


def test_the_rig_keeps_the_rig_contract() -> None:
    check("rig", "turntable", Registry(make_plugin_manager()))


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two cameras, four stage angles (a quarter turn a step)."""
    from agrisim.app.cli import main

    out = tmp_path_factory.mktemp("turntable") / "run"
    code = main(["run", "--rig", "turntable", "--setpoints", "2x4", *SMALL, "--out", str(out)])
    assert code == 0
    return out


def test_every_camera_shoots_at_every_stage_angle(run: Path) -> None:
    out = run
    doc = json.loads((out / layout.RUN_JSON).read_text())
    assert doc["config"]["rig"]["backend"] == "turntable"
    reached = sorted(r["frame"] for r in doc["results"] if r["reached"])
    assert reached == [f"c{c}_{k:03d}" for c in (1, 2) for k in range(4)]


@pytest.mark.parametrize(("room", "drawn"), [(None, "cabinet"), ("lab", "lab"), ("cabinet", "cabinet")])
def test_the_turntable_stands_in_the_cabinet_unless_a_room_is_named(room: str | None, drawn: str) -> None:
    """The cabinet is symmetric about the stage's axis (the orbit is then the turned plant
    exactly): the rig asks for it where ``[room] backend`` is not set, and a run records it."""
    from agrisim.config import build_config
    from agrisim.validation import check_run

    sections: dict = {"rig": {"backend": "turntable"}, "physics": {"backend": "kinematic"}}
    if room is not None:
        sections["room"] = {"backend": room}
    config = build_config(sections)
    check_run(Registry(make_plugin_manager()), config, preflight=False)
    assert config.room.backend == drawn
    assert build_config(json.loads(config.model_dump_json())).room.backend == drawn  # as run.json has it


def test_a_run_records_the_room_its_rig_asked_for(run: Path) -> None:
    assert json.loads((run / layout.RUN_JSON).read_text())["config"]["room"]["backend"] == "cabinet"


def test_the_cameras_orbit_the_plant_by_minus_the_stage_angle(run: Path) -> None:
    """In the plant's frame a camera at stage angle a is its pose at 0 turned by -a about the
    stage's axis; the two cameras stay on one column (the same azimuth, other heights)."""
    out = run
    frames = json.loads((out / layout.CAMERAS_JSON).read_text())["frames"]
    centre = np.array([0.0, 0.0, RunConfig().cell.table_height])
    for cam in ("c1", "c2"):
        first = np.asarray(frames[f"{cam}_000"]["world_T_camera"])
        for k in range(1, 4):
            expected = turn_z(-k * math.pi / 2, centre) @ first
            np.testing.assert_allclose(np.asarray(frames[f"{cam}_{k:03d}"]["world_T_camera"]), expected, atol=1e-6)
    for k in range(4):
        a, b = (np.asarray(frames[f"{c}_{k:03d}"]["world_T_camera"])[:3, 3] for c in ("c1", "c2"))
        assert math.isclose(math.atan2(a[1], a[0]), math.atan2(b[1], b[0]), abs_tol=1e-9) and a[2] > b[2]


def test_the_stage_keeps_its_speed_and_acceleration_limits(run: Path) -> None:
    """Every planned turn of the stage keeps within its default 30 deg/s and 30 deg/s^2 (its own,
    tighter than [motion]'s 4 rad/s^2), and a quarter turn takes what a trapezoid at those limits
    takes, D/v + v/a = 4 s, plus less than a tenth for the jerk's ramps; the run's clock agrees."""
    v, a = math.radians(30.0), math.radians(30.0)
    durations = []
    for path in sorted((run / layout.TRAJECTORIES).glob("c1_*.json"))[1:]:  # (the first shot needs no turn)
        planned = json.loads(path.read_text())["planned"]
        t, q, qd = (np.asarray(planned[k], float) for k in ("t", "q", "qd"))
        assert np.abs(qd).max() <= v * (1 + 1e-6)
        assert (np.abs(np.diff(qd, axis=0)) / np.diff(t)[:, None]).max() <= a * (1 + 1e-6)
        turn = float(np.abs(q[-1] - q[0]).max())
        assert turn == pytest.approx(math.pi / 2)
        durations.append(t[-1] - t[0])
        assert turn / v + v / a <= durations[-1] < turn / v + v / a + 0.1, durations
    results = json.loads((run / layout.RUN_JSON).read_text())["results"]
    times = sorted({round(r["sim_time"], 6) for r in results if r["frame"].startswith("c1_")})
    assert len(durations) == 3 and (np.diff(times) >= np.array(durations) - 1e-6).all()


def test_the_views_are_the_plant_turned_in_front_of_a_fixed_camera(run: Path) -> None:
    """Each view equals the view from the camera's first pose of the plant turned by the stage's
    angle (a quarter turn a step: exact in floating point): the same labels pixel for pixel, the
    same depth where the plant is seen. Rendered by raycast from the run's own camera poses."""
    from agrisim.config import RenderConfig
    from agrisim.plugins.plants.procedural import grow
    from agrisim.plugins.render.raycast import RaycastOptions
    from agrisim.plugins.render.raycast.renderer import RaycastRenderer
    from agrisim.plugins.rooms.lab.room import build_scene
    from agrisim.scene.camera import CameraModel

    out = run
    cameras = json.loads((out / layout.CAMERAS_JSON).read_text())
    K = np.asarray(cameras["intrinsics"]["K"])
    w, h = cameras["intrinsics"]["width"], cameras["intrinsics"]["height"]
    camera = CameraModel(w, h, K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    cell = TurntableRig(RunConfig().cell).cell()
    plant = grow(json.loads((out / layout.RUN_JSON).read_text())["config"]["plant"], 0)
    settings = RenderConfig(hide_robots=True)
    still = build_scene(cell, plant)
    first = np.asarray(cameras["frames"]["c1_000"]["world_T_camera"])
    for k in (1, 2, 3):
        orbit = RaycastRenderer(still, None, settings, RaycastOptions()).render(
            camera, np.asarray(cameras["frames"][f"c1_{k:03d}"]["world_T_camera"]), {}
        )
        # the plant (and its pot, round like the stage) turned by k quarter turns, seen from
        # the camera's first pose: (x, y) -> (-y, x) k times is exact in floating point
        turned = build_scene(cell, plant)
        for mesh in turned.meshes:
            if mesh.name == "plant":
                v = mesh.vertices.copy()
                for _ in range(k):
                    v[:, 0], v[:, 1] = -v[:, 1].copy(), v[:, 0].copy()
                mesh.vertices = v
        fixed = RaycastRenderer(turned, None, settings, RaycastOptions()).render(camera, first, {})
        assert (orbit.labels > 0).sum() > 50
        np.testing.assert_array_equal(orbit.labels, fixed.labels)
        seen = orbit.labels > 0
        np.testing.assert_allclose(orbit.depth[seen], fixed.depth[seen], rtol=1e-5)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--set", "rig.turntable.tilts_deg=[10]"], "tilts_deg gives 1 tilts for 3 cameras"),
        (["--set", "rig.turntable.stage_radius=0.6"], "leaves the cameras at 0.5 m no room"),
        (["--set", "rig.turntable.heights=[]"], "heights"),
    ],
    ids=["tilts", "stage", "no-camera"],
)
def test_bad_input_is_refused_in_one_line(args: list[str], says: str, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "never"
    code, _, err = cli(["run", "--rig", "turntable", *args, "--setpoints", "1x2", *SMALL, "--out", str(out)])
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert "Traceback" not in err and not out.exists()


def test_options_default_to_three_cameras_aimed_at_the_plant() -> None:
    rig = TurntableRig(RunConfig().cell, TurntableOptions())
    aim = RunConfig().routine.aim_height
    for height, tilt in zip(rig.options.heights, rig.tilts(), strict=True):
        assert math.isclose(math.tan(tilt) * rig.options.distance, height - aim)


def test_nextview_chooses_among_the_stage_angles_and_cameras(tmp_path: Path, cli) -> None:  # noqa: ANN001
    """``agrisim nextview`` on the turntable: its candidates are the rig's own (a camera at a
    stage angle), the paper policy takes them all, random a few, and every view is reached."""
    out = tmp_path / "nv"
    args = ["nextview", "--plant", "coltsfoot", "--views", "3", "--resolution", "64x36", "--policies", "paper,random"]
    code, stdout, err = cli(
        [*args, "--set", "rig.backend=turntable", "--set", "physics.backend=kinematic", "--out", str(out)]
    )
    assert code == 0, err
    episodes = json.loads((out / "nextview.json").read_text())["plants"]["coltsfoot"]
    # the default candidates (5x10): all three cameras (fewer than five levels) at ten angles
    assert len(episodes["paper"]["coverage"]) == 3 * 10 and len(episodes["random"]["coverage"]) == 3
    assert all(e["reach_failures"] == 0 for e in episodes.values())
    assert "paper, 30 views" in stdout
    assert episodes["paper"]["coverage"][-1] > episodes["random"]["coverage"][-1] > 0.0
