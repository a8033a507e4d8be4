"""The paper's hemisphere routine and CSV setpoints, checked against their geometry."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from agrisim.config import RoutineConfig
from agrisim.errors import UserError
from agrisim.plugins.rigs.paper.cell import hemisphere
from agrisim.robot.setpoints import from_csv


def test_hemisphere_matches_the_paper(cell):
    sps = hemisphere(cell, RoutineConfig())
    assert [len(v) for v in sps.values()] == [50, 50]
    c = cell.plant_center
    phis = np.linspace(np.pi / 5, 3 * np.pi / 7, 5)
    for robot, points in sps.items():
        base = cell.arm(robot).world_T_base[:3, 3]
        for sp in points:
            T = sp.world_T_camera
            d = T[:3, 3] - c
            assert abs(np.linalg.norm(d) - 0.5) < 1e-12
            # the camera looks at the aim point above the centre, image up towards world up
            to_aim = c + np.array([0.0, 0.0, 0.2]) - T[:3, 3]
            np.testing.assert_allclose(T[:3, 2], to_aim / np.linalg.norm(to_aim), atol=1e-12)
            assert T[2, 1] < 0  # optical y (down in the image) points down in the world
            np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
            # every setpoint lies on its arm's half of the hemisphere
            assert np.dot(d[:2], base[:2] - c[:2]) > 0
        polar = sorted({round(float(np.arccos((p.world_T_camera[2, 3] - c[2]) / 0.5)), 9) for p in points})
        np.testing.assert_allclose(polar, phis, atol=1e-9)


def test_snake_order_keeps_neighbours_adjacent(cell):
    points = hemisphere(cell, RoutineConfig())["r1"]
    steps = [np.linalg.norm(a.world_T_camera[:3, 3] - b.world_T_camera[:3, 3]) for a, b in itertools.pairwise(points)]
    # consecutive setpoints are neighbours: no jump across the hemisphere between levels
    assert max(steps) < 0.2
    assert [p.frame for p in points[:2]] == ["r1_000", "r1_001"]


def test_azimuths_span_each_half(cell):
    points = hemisphere(cell, RoutineConfig(setpoints="1x10"))["r1"]
    c = cell.plant_center
    az = [np.arctan2(p.world_T_camera[1, 3] - c[1], p.world_T_camera[0, 3] - c[0]) for p in points]
    # r1 faces +x: azimuths from -pi/2 + pi/19 to -pi/2 + 18pi/19
    np.testing.assert_allclose(az, np.linspace(np.pi / 19, 18 * np.pi / 19, 10) - np.pi / 2, atol=1e-9)


def test_csv_setpoints(cell, tmp_path):
    f = tmp_path / "sp.csv"
    f.write_text("robot,x,y,z,roll,pitch,yaw\nr2,-0.3,0.1,1.1,0,1.5707963267948966,0\nr1,0.3,0,1.0,3.14159,0,0\n")
    sps = from_csv(cell, f)
    assert len(sps["r1"]) == 1 and len(sps["r2"]) == 1
    T = sps["r2"][0].world_T_camera
    np.testing.assert_allclose(T[:3, 3], [-0.3, 0.1, 1.1])
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-9)  # pitch 90 deg turns z onto x


@pytest.mark.parametrize(
    "text, message",
    [
        ("a,b\n1,2\n", "needs a header"),
        ("x,y,z,roll,pitch,yaw\n1,2,three,0,0,0\n", "must be numbers"),
        ("robot,x,y,z,roll,pitch,yaw\nr9,0,0,1,0,0,0\n", "unknown robot"),
        ("x,y,z,roll,pitch,yaw\nnan,0,1,0,0,0\n", "finite"),
    ],
)
def test_bad_csv_is_a_clear_error(cell, tmp_path, text, message):
    f = tmp_path / "sp.csv"
    f.write_text(text)
    with pytest.raises(UserError, match=message):
        from_csv(cell, f)
