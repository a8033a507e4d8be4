"""The imaging cabinet of a turntable phenotyping station as a :class:`agrisim.scene.model.Scene`.

Backend-free (numpy only), world coordinates, everything centred on the stage axis (the
vertical line through :attr:`agrisim.robot.cell.Cell.plant_center`):

* a floor disc, a cylindrical backdrop and a ceiling disc of ``radius``, each one plain matte
  material (no texture: a texture would not look the same turned about the axis);
* the turntable's plate (``stage``) under the pot (or the cell's own obstacle named ``stage``,
  where the rig gives one, in the plate's colour), the pot and soil as the lab draws them
  (:func:`agrisim.plugins.rooms.lab.room.pot_meshes`), the table and any other obstacle at
  its exact size and pose in one plain material;
* one lamp on the axis below the ceiling facing down: an area light (a disc) or a spot light
  over the lower hemisphere;
* the plant on the soil (:func:`agrisim.robot.cell.place_plant`), label ids as the lab's:
  everything but the plant is background (0).

Why it is symmetric: a turntable rig renders in the stage's frame, so what stands on the stage
(:data:`TURNS_WITH_STAGE`) is fixed and everything else must look the same from every angle
about the axis. The discs and the backdrop are polygons of ``WALL_SEGMENTS`` sides, the
plate's and the pot's of 48, multiples of 4: a quarter turn maps each mesh onto itself
exactly; other angles only up to the polygon's facets. A ``Box`` obstacle (the paper's square
table, the arms' stands) is not symmetric, so a turntable rig gives a round table (a
``Cylinder`` named ``table``) and no stands.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from agrisim import interfaces
from agrisim.errors import UserError
from agrisim.plugins.mesh_builder import MeshBuilder
from agrisim.plugins.rooms.cabinet import CabinetOptions, Colour
from agrisim.plugins.rooms.lab.clutter import has_visual
from agrisim.plugins.rooms.lab.primitives import cylinder_side, disc
from agrisim.plugins.rooms.lab.room import POT_SEGMENTS, Materials, obstacle_meshes
from agrisim.robot.cell import Cell, Cylinder, Obstacle, place_plant, soil_pose
from agrisim.scene.model import Light, Material, Mesh, Plant, Scene
from agrisim.scene.transforms import translation

WALL_SEGMENTS = 96
"""Sides of the floor, backdrop, ceiling and lamp polygons (a multiple of 4: see the module)."""
TURNS_WITH_STAGE = ("plant", "pot", "soil", "stage")
"""Meshes that stand on the turntable: on a real station they turn with the plant, so in the
stage's frame they are fixed with it and need not be symmetric (the pot's clay is textured)."""
LAMP_DROP = 0.02
"""How far below the ceiling the light is, m; its panel is drawn above it, out of its way."""
LAMP_COLOR = (1.0, 0.98, 0.95)


def _plain(name: str, rgb: Colour, roughness: float) -> Material:
    return Material(name, color=(*rgb, 1.0), roughness=roughness)


def reach(ob: Obstacle, axis: np.ndarray) -> float:
    """How far ``ob``'s footprint reaches from the vertical line through ``axis`` (x, y), m."""
    centre = ob.world_T[:2, 3] - axis
    if isinstance(ob, Cylinder):
        return float(np.linalg.norm(centre) + ob.radius)
    half = np.array([[sx, sy] for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)]) * np.asarray(ob.size[:2]) / 2
    corners = half @ ob.world_T[:2, :2].T + centre
    return float(np.linalg.norm(corners, axis=1).max())


def check_fits(cell: Cell, options: CabinetOptions) -> None:
    """Raise :class:`UserError` when an obstacle or an arm's base stands outside the backdrop or
    above the ceiling (it would be drawn through the cabinet's walls)."""
    axis = np.asarray(cell.plant_center, float)[:2]
    for ob in cell.obstacles:
        if not has_visual(ob):
            continue
        top = ob.world_T[2, 3] + (ob.height if isinstance(ob, Cylinder) else ob.size[2]) / 2
        out = reach(ob, axis)
        if out > options.radius or top > options.height:
            raise UserError(
                f"room cabinet: {ob.name} reaches {out:.2f} m from the stage axis and {top:.2f} m up, outside the "
                f"cabinet's backdrop ({options.radius:.2f} m, {options.height:.2f} m high); set room.cabinet.radius "
                "or room.cabinet.height"
            )
    for arm in cell.arms:
        out = float(np.linalg.norm(arm.world_T_base[:2, 3] - axis))
        if out > options.radius:
            raise UserError(
                f"room cabinet: arm {arm.name}'s base is {out:.2f} m from the stage axis, outside the cabinet's "
                f"backdrop ({options.radius:.2f} m); set room.cabinet.radius"
            )


def _shell(axis: np.ndarray, options: CabinetOptions) -> list[Mesh]:
    """Floor, backdrop and ceiling of ``radius`` about the axis."""
    R, H, n = options.radius, options.height, WALL_SEGMENTS
    at = translation(axis[0], axis[1], 0.0)
    parts = (
        ("floor", disc(R, 0.0, n), _plain("cabinet_floor", options.floor_color, 0.7)),
        ("backdrop", cylinder_side(R, 0.0, H, n, inward=True), _plain("backdrop", options.backdrop_color, 0.95)),
        ("ceiling", disc(R, H, n, up=False), _plain("cabinet_ceiling", options.ceiling_color, 0.95)),
    )
    meshes = []
    for name, part, material in parts:
        b = MeshBuilder()
        b.add_part(part, material)
        meshes.append(b.build(name, T=at))
    return meshes


def _stage(cell: Cell, axis: np.ndarray, options: CabinetOptions) -> list[Mesh]:
    """The turntable's plate standing on what the pot stands on, the pot's foot inside it (its
    top face is never coplanar with the table's, whose tie a renderer would break at random)."""
    pot = next((ob for ob in cell.obstacles if ob.name == "pot"), None)
    own = any(ob.name == "stage" for ob in cell.obstacles)  # the rig's: drawn as its obstacle
    if not isinstance(pot, Cylinder) or options.stage_height <= 0 or own:
        return []
    r = max(options.stage_radius, pot.radius + 0.01)
    z0 = float(pot.world_T[2, 3] - pot.height / 2)
    h = options.stage_height
    plate = _plain("stage", options.stage_color, 0.5)
    b = MeshBuilder()
    b.add_part(cylinder_side(r, 0.0, h, POT_SEGMENTS), plate)
    b.add_part(disc(r, h, POT_SEGMENTS), plate)
    return [b.build("stage", T=translation(axis[0], axis[1], z0))]


def _lamp(axis: np.ndarray, target_z: float, options: CabinetOptions) -> tuple[Light, list[Mesh]]:
    """The light on the axis under the ceiling, facing down, giving ``irradiance`` at
    ``target_z`` on the axis (I / d^2, the light's axis pointing at it), and its panel."""
    z = options.height - LAMP_DROP
    position = np.array([axis[0], axis[1], z])
    d = max(z - target_z, 0.1)
    intensity = options.irradiance * d**2
    down = np.array([0.0, 0.0, -1.0])
    if options.lamp_radius == 0:
        # a spot of the whole lower hemisphere, not a point: a point this close under the
        # ceiling lights it far more than anything else, and Mitsuba's bounces off it made the
        # room's median 148 against the area lamp's 91 (8-bit), the raycast renderer's 102
        return Light("cabinet_lamp", "spot", position, down, LAMP_COLOR, intensity, cone_deg=90.0), []
    light = Light("cabinet_lamp", "area", position, down, LAMP_COLOR, intensity, options.lamp_radius)
    b = MeshBuilder()
    panel = Material("lamp_panel", color=(1.0, 1.0, 1.0, 1.0), roughness=0.9)
    b.add_part(disc(options.lamp_radius, 0.0, WALL_SEGMENTS, up=False), panel)
    return light, [b.build("lamp_panel", T=translation(axis[0], axis[1], options.height - 0.004))]


def build_scene(
    cell: Cell,
    plant: Plant,
    options: CabinetOptions | None = None,
    *,
    labels: Literal["plant", "organs"] | str = "plant",
) -> Scene:
    """The cabinet around ``cell`` with ``plant`` in its pot (``options``: the defaults of
    :class:`CabinetOptions` when None). Nothing is random: the run's seed changes nothing."""
    if options is None:
        options = CabinetOptions()
    placed = place_plant(plant, cell, labels)
    axis = np.asarray(cell.plant_center, float)[:2]
    mats = Materials()
    plain = _plain("cabinet_obstacle", options.obstacle_color, 0.6)
    plate = _plain("stage", options.stage_color, 0.5)
    meshes = _shell(axis, options) + _stage(cell, axis, options)
    for ob in cell.obstacles:
        if has_visual(ob):
            meshes.extend(obstacle_meshes(ob, mats, plate if ob.name == "stage" else plain))
    if placed.points is None:
        meshes.append(placed.mesh)
    drawn = placed.drawn
    # the plant's middle height: on the axis whatever the plant's shape, so the lamp stays there
    target_z = float(drawn[:, 2].min() + drawn[:, 2].max()) / 2 if len(drawn) else float(soil_pose(cell)[2, 3])
    light, panel = _lamp(axis, target_z, options)
    meshes.extend(panel)
    return Scene(
        meshes=meshes, lights=[light], labels=placed.labels, plant="plant", points=placed.points, source=placed.source
    )


class Cabinet(interfaces.Room):
    """The ``cabinet`` room: :func:`build_scene` for the run's cell with its ``[room.cabinet]``
    options. Built only where the cell fits inside the backdrop (:func:`check_fits`)."""

    def __init__(self, cell: Cell, options: CabinetOptions) -> None:
        super().__init__(cell, options)
        check_fits(cell, options)

    def scene(self, plant: Plant, *, seed: int, labels: str) -> Scene:
        return build_scene(self.cell, plant, self.options, labels=labels)
