"""The ``cabinet`` room: what a turntable rig's images rest on. Rendering in the stage's frame
(the plant still, the cameras orbiting it) gives the turntable's images only if everything that
does not turn with the stage looks the same turned about the stage axis. A quarter turn is
exact in floating point ((x, y) -> (-y, x) about an axis through the origin), so the truth is
plain: the view from a camera and the view from that camera turned a quarter about the axis,
with what stands on the stage turned the same quarter, are the same image. The lab is not
symmetric, and the same comparison fails there."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agrisim.config import RenderConfig
from agrisim.errors import UserError
from agrisim.interfaces import Frame
from agrisim.plugins.plants.procedural import grow
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.renderer import RaycastRenderer
from agrisim.plugins.rooms.cabinet import CabinetOptions
from agrisim.plugins.rooms.cabinet.room import TURNS_WITH_STAGE, Cabinet, build_scene
from agrisim.plugins.rooms.lab.room import build_scene as lab_scene
from agrisim.robot.cell import Box, Cell, Cylinder
from agrisim.scene.camera import from_fov
from agrisim.scene.encoding import depth_to_mm
from agrisim.scene.model import Mesh, Plant, Scene
from agrisim.scene.transforms import look_at, translation

#: a quarter turn about z: its entries 0 and +-1 keep every coordinate exact
QUARTER = np.array([[0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
CAMERA = from_fov(60.0, 160, 120)
#: a camera 0.9 m from the axis at azimuth 20 degrees, looking down at the plant past the table's
#: edge: backdrop, floor, table, plate, pot and plant (and their shadows) in one view. Not a
#: multiple of 3.75 degrees: there the image's middle column lies in the plane of the discs'
#: radial edges, and rays exactly on an edge slip through it in either view, at random (Embree's
#: intersection is not watertight there): holes that are the renderer's, not the room's.
EYE = np.array([0.9 * np.cos(np.radians(20.0)), 0.9 * np.sin(np.radians(20.0)), 1.45])
VIEW = look_at(EYE, np.array([0.0, 0.0, 0.85]))


def turntable_cell() -> Cell:
    """A turntable station's cell: a round table under the pot, the stage axis through the
    origin, no arms (a rig's cameras orbit; the renders hide robots)."""
    top = 0.8
    return Cell(
        arms=(),
        obstacles=(
            Box("floor", (6.0, 6.0, 0.02), translation(0.0, 0.0, -0.01)),
            Cylinder("table", 0.3, top, translation(0.0, 0.0, top / 2)),
            Cylinder("pot", 0.09, 0.14, translation(0.0, 0.0, top + 0.07)),
        ),
        plant_center=np.array([0.0, 0.0, top]),
    )


@pytest.fixture(scope="module")
def plant() -> Plant:
    return grow("hydrangea", 3)


def quarter_turned(scene: Scene, names: tuple[str, ...]) -> Scene:
    """``scene`` with the meshes of ``names`` turned a quarter about the z axis, exactly."""

    def turn(m: Mesh) -> Mesh:
        V = m.vertices
        return dataclasses.replace(m, vertices=np.column_stack([-V[:, 1], V[:, 0], V[:, 2]]))

    return dataclasses.replace(scene, meshes=[turn(m) if m.name in names else m for m in scene.meshes])


def render(scene: Scene, world_T_camera: np.ndarray, shadow_samples: int) -> Frame:
    renderer = RaycastRenderer(
        scene, None, RenderConfig(hide_robots=True), RaycastOptions(shadow_samples=shadow_samples)
    )
    try:
        return renderer.render(CAMERA, world_T_camera, {})
    finally:
        renderer.close()


def differences(scene: Scene, turning: tuple[str, ...], shadow_samples: int) -> tuple[Frame, dict[str, int]]:
    """The view ``VIEW`` of ``scene`` and how the quarter-turned view of the quarter-turned
    ``turning`` meshes differs from it: label pixels that differ, the largest depth difference
    in depth/'s encoding (mm), the largest RGB difference (8-bit)."""
    a = render(scene, VIEW, shadow_samples)
    b = render(quarter_turned(scene, turning), QUARTER @ VIEW, shadow_samples)
    mm = np.abs(depth_to_mm(a.depth).astype(np.int64) - depth_to_mm(b.depth).astype(np.int64))
    return a, {
        "labels": int((a.labels != b.labels).sum()),
        "depth_mm": int(mm.max()),
        "rgb": int(np.abs(a.rgb.astype(np.int64) - b.rgb.astype(np.int64)).max()),
        "rgb_pixels": int((a.rgb != b.rgb).any(axis=2).sum()),
    }


@pytest.mark.parametrize(
    ("options", "shadow_samples"),
    [(CabinetOptions(), 0), (CabinetOptions(lamp_radius=0.0), 4)],
    ids=["area-lamp", "spot-lamp-shadows"],
)
def test_the_cabinet_looks_the_same_a_quarter_turn_round(
    plant: Plant, options: CabinetOptions, shadow_samples: int
) -> None:
    """Labels pixel for pixel, depth and RGB within a unit of their encodings (the renderer's
    float sums may round differently in the other order). The area lamp without shadow rays and
    the spot lamp (lamp_radius 0) with them: the raycast renderer aims shadow rays at a disc's points in a
    spiral that a quarter turn does not map onto itself, so an area lamp's penumbrae carry
    sampling noise that differs between the two views."""
    scene = build_scene(turntable_cell(), plant, options)
    a, diff = differences(scene, TURNS_WITH_STAGE, shadow_samples)
    # the view holds what the comparison is about: plant, and the room's surfaces behind it
    assert (a.labels > 0).sum() > 500 and (a.labels == 0).sum() > 5000
    assert len(np.unique(a.rgb.reshape(-1, 3)[::7], axis=0)) > 100
    assert diff["labels"] == 0, diff
    assert diff["depth_mm"] <= 1, diff
    assert diff["rgb"] <= 1, diff


def test_the_lab_does_not(plant: Plant) -> None:
    """The same comparison in the lab (its room rectangular, its ceiling lights beside the
    plant, its surfaces textured) tells the views apart: the test above can fail."""
    scene = lab_scene(turntable_cell(), plant)
    _, diff = differences(scene, TURNS_WITH_STAGE, 0)
    assert diff["rgb"] > 20 and diff["rgb_pixels"] > 1000, diff


def test_a_backdrop_that_cuts_through_the_rig_is_refused(cell: Cell) -> None:
    """The paper's stands reach 1.22 m from the axis: inside the default 1.5 m backdrop, through
    a 1.1 m one (its arms' bases, 1 m out, would still fit)."""
    Cabinet(cell, CabinetOptions())
    with pytest.raises(UserError, match="r1_stand reaches 1.22 m"):
        Cabinet(cell, CabinetOptions(radius=1.1))
    with pytest.raises(UserError, match="arm r1's base is 1.00 m"):
        Cabinet(dataclasses.replace(cell, obstacles=()), CabinetOptions(radius=0.9))


def test_a_rigs_own_stage_replaces_the_plate(plant: Plant) -> None:
    """A rig that models the turntable as an obstacle named ``stage`` gets it drawn once, at its
    size, in the plate's colour; without one the room's plate stands under the pot."""
    cell = turntable_cell()
    plate = build_scene(cell, plant).mesh("stage")
    assert np.isclose(plate.vertices[:, 2].min(), 0.8) and np.isclose(plate.vertices[:, 2].max(), 0.82)
    own = Cylinder("stage", 0.2, 0.05, translation(0.0, 0.0, 0.775))
    scene = build_scene(dataclasses.replace(cell, obstacles=(*cell.obstacles, own)), plant)
    stages = [m for m in scene.meshes if m.name == "stage"]
    assert len(stages) == 1 and np.isclose(np.abs(stages[0].vertices[:, :2]).max(), 0.2)
    assert stages[0].materials[0].color[:3] == CabinetOptions().stage_color
