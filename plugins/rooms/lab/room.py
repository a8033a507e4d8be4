"""The lab around the robot cell as a :class:`agrisim.scene.model.Scene`: room, furniture, lights,
the seeded clutter randomizer of the paper (section 3.3), and the plant placed in its pot.

Backend-free (numpy only). Everything is built in world coordinates:

* a room (10 x 8 m, 3 m high by default, centred on the plant) with a tiled floor, painted
  walls with a skirting board and an acoustic-tile ceiling;
* the table, the pot and the robot stands drawn from :attr:`agrisim.robot.cell.Cell.obstacles`, with
  exactly the physics bodies' sizes and poses (renders and collisions agree); the pot is a clay
  shell with a rim and a soil disc set ``SOIL_INSET`` below its rim;
* the plant moved from its own frame (origin at the centre of the soil surface) onto the soil;
* four area lights as in the paper: two on the ceiling facing down, two on the robot stands
  facing the plant;
* the PCG clutter: cabinets, pallets and drums sampled at 0.1 / 0.5 / 0.75 per m^2 of floor,
  turned by U(0, 180 deg) about z, never centred in the middle 6 x 4 m, never through a wall,
  overlaps removed with priority cabinet > pallet > drum. :func:`clutter_layout` gives the layout
  alone (deterministic in the seed).

Label ids: everything but the plant is background (0). With ``labels="plant"`` the plant's
label textures are remapped so that every organ becomes ``plant`` (1); with ``labels="organs"``
the plant keeps its own label table.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from agrisim import interfaces
from agrisim.plugins.mesh_builder import MeshBuilder
from agrisim.plugins.rooms.lab import textures as tex
from agrisim.plugins.rooms.lab.clutter import Item, Room, cell_keepouts, clutter_layout, has_visual, room_for
from agrisim.plugins.rooms.lab.primitives import annulus, box, cylinder_side, disc, quad
from agrisim.robot.cell import SOIL_INSET, Box, Cell, Cylinder, place_plant, soil_pose
from agrisim.scene.model import Light, Material, Mesh, Plant, Scene
from agrisim.scene.transforms import translation, yaw_matrix

POT_WALL = 0.008
"""Thickness of the pot's wall seen at its rim, m (capped at a third of its radius)."""
POT_SEGMENTS = 48
"""Sides of the pot's polygon (a multiple of 4, so that its bounding box is the cylinder's)."""
DRUM_SEGMENTS = 24
CEILING_IRRADIANCE = 0.35
"""Irradiance each ceiling light gives the plant (1 = white on white), renderer-relative."""
STAND_IRRADIANCE = 0.3
"""Irradiance each stand lamp gives the plant's side facing it."""


# --------------------------------------------------------------------------------------------
# Materials
# --------------------------------------------------------------------------------------------

CABINET_COLORS = ((0.56, 0.58, 0.61), (0.30, 0.40, 0.55), (0.80, 0.76, 0.66))
DRUM_COLORS = ((0.10, 0.24, 0.58), (0.62, 0.11, 0.09), (0.14, 0.40, 0.20), (0.86, 0.62, 0.08))


class Materials:
    """One :class:`Material` per look, made on first use and shared by the meshes of a scene."""

    def __init__(self) -> None:
        self._cache: dict[tuple[Any, ...], Material] = {}

    def get(self, key: tuple[Any, ...], make: Callable[[], Material]) -> Material:
        """The material of ``key``, made by ``make`` the first time."""
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def textured(
        self,
        name: str,
        albedo: np.ndarray,
        color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
        roughness: float = 0.8,
    ) -> Material:
        """A material of ``albedo`` (an sRGB texture) times ``color``, one per name and colour."""
        return self.get((name, color), lambda: Material(name, color=color, albedo=albedo, roughness=roughness))


# --------------------------------------------------------------------------------------------
# Scene parts
# --------------------------------------------------------------------------------------------


def _room_meshes(room: Room, mats: Materials) -> list[Mesh]:
    cx, cy = room.center
    hx, hy, H = room.size[0] / 2, room.size[1] / 2, room.height
    floor = MeshBuilder()
    tiles = mats.textured("floor_tiles", tex.floor_tiles(), roughness=0.35)
    floor.add_part(quad((cx, cy, 0.0), (hx, 0, 0), (0, hy, 0), (2 * hx / 2.4, 2 * hy / 2.4)), tiles)
    ceiling = MeshBuilder()
    ceiling.add_part(
        quad((cx, cy, H), (hx, 0, 0), (0, -hy, 0), (2 * hx / 1.2, 2 * hy / 1.2)),
        mats.textured("ceiling_tiles", tex.ceiling_tiles(), roughness=0.95),
    )
    walls = MeshBuilder()
    paint = mats.textured("wall_paint", tex.wall_paint(), roughness=0.85)
    for nx, ny, half in ((0, 1, hx), (0, -1, hx), (1, 0, hy), (-1, 0, hy)):
        inward = np.array([nx, ny, 0.0])
        centre = np.array([cx, cy, H / 2]) - inward * np.array([hx, hy, 0.0])
        a = np.cross([0.0, 0.0, 1.0], inward) * half  # a x b = inward
        walls.add_part(quad(centre, a, (0, 0, H / 2), (2 * half / 2.0, 1.0)), paint)
    return [floor.build("floor"), walls.build("walls"), ceiling.build("ceiling")]


def pot_meshes(pot: Cylinder, mats: Materials) -> list[Mesh]:
    """The pot as the lab draws it, at ``pot``'s size and pose: a terracotta shell with a rim
    (``POT_WALL``) and a soil disc ``SOIL_INSET`` below it, ``POT_SEGMENTS`` sides; meshes
    ``pot`` and ``soil`` (a bench's ``pot_01`` and ``soil_01``...)."""
    r, h = pot.radius, pot.height
    wall, inset = min(POT_WALL, r / 3), min(SOIL_INSET, h / 3)
    clay = mats.textured("terracotta", tex.terracotta(), roughness=0.9)
    inner = mats.textured("terracotta_inner", tex.terracotta(), (0.62, 0.62, 0.62, 1.0), 0.9)
    b = MeshBuilder()
    b.add_part(cylinder_side(r, -h / 2, h / 2, POT_SEGMENTS, u_repeats=2.0), clay)
    b.add_part(annulus(r - wall, r, h / 2, POT_SEGMENTS), clay)
    b.add_part(cylinder_side(r - wall, h / 2 - inset, h / 2, POT_SEGMENTS, inward=True, u_repeats=2.0), inner)
    soil = MeshBuilder()
    soil.add_part(disc(r - wall, h / 2 - inset, POT_SEGMENTS), mats.textured("soil", tex.soil(), roughness=1.0))
    return [b.build(pot.name, T=pot.world_T), soil.build("soil" + pot.name[3:], T=pot.world_T)]


def obstacle_meshes(ob: Box | Cylinder, mats: Materials, plain: Material | None = None) -> list[Mesh]:
    """``ob`` drawn at its exact size and pose (renders and collisions agree): the pot by
    :func:`pot_meshes`, a cylinder with its caps, a box without the face it stands on on the
    floor. ``plain``: one material for all but the pot instead of the lab's textured table top,
    metal and stands (a room whose surfaces must look the same turned about an axis cannot have
    textures that do not turn with it)."""
    if isinstance(ob, Cylinder) and (ob.name == "pot" or ob.name.startswith("pot_")):  # a bench's pot_01...
        return pot_meshes(ob, mats)
    b = MeshBuilder()
    if isinstance(ob, Cylinder):
        metal = plain or mats.textured("metal_light", tex.painted_metal((0.7, 0.7, 0.72), 1), roughness=0.4)
        b.add_part(cylinder_side(ob.radius, -ob.height / 2, ob.height / 2, POT_SEGMENTS), metal)
        b.add_part(disc(ob.radius, ob.height / 2, POT_SEGMENTS), metal)
        b.add_part(disc(ob.radius, -ob.height / 2, POT_SEGMENTS, up=False), metal)
        return [b.build(ob.name, T=ob.world_T)]
    on_floor = abs(ob.world_T[2, 3] - ob.size[2] / 2) < 1e-9
    faces = box(ob.size, skip=("-z",) if on_floor else ())
    if plain is not None:
        b.add_parts(faces.values(), plain)
    elif ob.name == "table":
        top = mats.textured("laminate", tex.laminate(), roughness=0.45)
        side = mats.textured("table_side", tex.painted_metal((0.84, 0.85, 0.87), 2), roughness=0.4)
        for name, part in faces.items():
            b.add_part(part, top if name == "+z" else side)
    else:  # stands and anything else: dark powder-coated steel
        b.add_parts(
            faces.values(), mats.textured("stand_metal", tex.painted_metal((0.27, 0.28, 0.30), 3), roughness=0.5)
        )
    return [b.build(ob.name, T=ob.world_T)]


def _cabinet(item: Item, mats: Materials) -> Mesh:
    k = item.spec
    color = CABINET_COLORS[item.variant % len(CABINET_COLORS)]
    size = (k.size[0], k.size[1], k.height)
    faces = box(size, (0, 0, k.height / 2), skip=("-z",))
    front = box(size, (0, 0, k.height / 2), repeat=None)["-y"]
    b = MeshBuilder()
    body = mats.textured(f"cabinet_body_{item.variant}", tex.painted_metal(color, 10 + item.variant), roughness=0.45)
    for name, part in faces.items():
        if name == "-y":
            b.add_part(front, mats.textured(f"cabinet_front_{item.variant}", tex.cabinet_front(color), roughness=0.45))
        else:
            b.add_part(part, body)
    return b.build(f"cabinet_{item.index:03d}", T=item.world_T)


def _pallet(item: Item, mats: Materials) -> Mesh:
    """An EUR pallet (1.2 x 0.8 x 0.144 m) of real slats: 3 bottom boards, 9 blocks, 3 cross
    boards, 5 top deck boards."""
    wood = mats.textured(f"pallet_wood_{item.variant}", tex.wood(item.variant), roughness=0.85)
    rng = np.random.default_rng([item.variant, 77])  # boards differ, pallets of a variant agree
    b = MeshBuilder()
    t = 0.022
    rot = yaw_matrix(np.pi / 2)

    def board(length: float, width: float, height: float, x: float, y: float, z: float, across: bool = False) -> None:
        offset = (float(rng.random()), float(rng.random()))
        faces = box((length, width, height), repeat=(1.0, 0.25), skip=("-z",), uv_offset=offset)
        T = translation(x, y, z + height / 2) @ (rot if across else np.eye(4))
        b.add_parts(faces.values(), wood, T)

    rows = (-0.35, 0.0, 0.35)
    cols = (-0.5275, 0.0, 0.5275)
    for y in rows:
        board(1.2, 0.1 if y else 0.145, t, 0.0, y, 0.0)
    for x in cols:
        for y in rows:
            board(0.145, 0.1, 0.078, x, y, t)
    for x in cols:
        board(0.8, 0.145, t, x, 0.0, t + 0.078, across=True)
    for y in (-0.35, -0.175, 0.0, 0.175, 0.35):
        board(1.2, 0.1, t, 0.0, y, 2 * t + 0.078)
    return b.build(f"pallet_{item.index:03d}", T=item.world_T)


def _drum(item: Item, mats: Materials) -> Mesh:
    k = item.spec
    color = DRUM_COLORS[item.variant % len(DRUM_COLORS)]
    r = k.size[0] / 2
    b = MeshBuilder()
    side = mats.textured(f"drum_side_{item.variant}", tex.drum_side(color), roughness=0.4)
    b.add_part(cylinder_side(r, 0.0, k.height, DRUM_SEGMENTS), side)
    b.add_part(
        disc(r, k.height, DRUM_SEGMENTS), mats.textured(f"drum_lid_{item.variant}", tex.drum_lid(color), roughness=0.4)
    )
    return b.build(f"drum_{item.index:03d}", T=item.world_T)


_CLUTTER_BUILDERS = {"cabinet": _cabinet, "pallet": _pallet, "drum": _drum}


def _intensity(irradiance: float, position: np.ndarray, direction: np.ndarray, target: np.ndarray) -> float:
    """Axial intensity giving ``irradiance`` at ``target`` (facing the light): E = I cos / d^2."""
    d = target - position
    dist = float(np.linalg.norm(d))
    cos = max(float(np.dot(direction, d / dist)), 0.2)
    return irradiance * dist**2 / cos


def _lights(cell: Cell, room: Room, target: np.ndarray, mats: Materials) -> tuple[list[Light], list[Mesh]]:
    """Two ceiling panels facing down either side of the plant (along y, clear of the arms) and a
    lamp on each robot stand's inner edge facing the plant."""
    lights: list[Light] = []
    meshes: list[Mesh] = []
    panel = mats.get(("lamp_panel",), lambda: Material("lamp_panel", color=(1.0, 1.0, 1.0, 1.0), roughness=0.9))
    radius = 0.3
    for i, side in enumerate((1.0, -1.0), start=1):
        pos = np.array([target[0], target[1] + 0.9 * side, room.height - 0.02])
        down = np.array([0.0, 0.0, -1.0])
        lights.append(
            Light(
                f"ceiling_{i}",
                "area",
                pos,
                down,
                (1.0, 0.97, 0.92),
                _intensity(CEILING_IRRADIANCE, pos, down, target),
                radius,
            )
        )
        b = MeshBuilder()
        b.add_part(disc(radius, 0.0, 24, up=False), panel, translation(pos[0], pos[1], room.height - 0.004))
        meshes.append(b.build(f"lamp_ceiling_{i}"))
    obstacles = {ob.name: ob for ob in cell.obstacles}
    for arm in cell.arms:
        stand = obstacles.get(arm.stand)
        if not isinstance(stand, Box):
            continue
        centre = stand.world_T[:3, 3]
        toward = target[:2] - centre[:2]
        toward /= max(np.linalg.norm(toward), 1e-9)
        lateral = np.array([-toward[1], toward[0]])  # the same hand for every stand
        xy = centre[:2] + toward * 0.35 * stand.size[0] + lateral * 0.3 * stand.size[1]
        pos = np.array([xy[0], xy[1], centre[2] + stand.size[2] / 2 + 0.2])
        direction = (target - pos) / np.linalg.norm(target - pos)
        lights.append(
            Light(
                f"{arm.stand}_lamp",
                "area",
                pos,
                direction,
                (1.0, 1.0, 1.0),
                _intensity(STAND_IRRADIANCE, pos, direction, target),
                0.15,
            )
        )
    return lights, meshes


def build_scene(
    cell: Cell,
    plant: Plant,
    *,
    pcg_seed: int = 42,
    labels: Literal["plant", "organs"] | str = "plant",
    room: Room | None = None,
) -> Scene:
    """The lab scene for ``cell`` with ``plant`` in its pot and the clutter of ``pcg_seed``.

    Lights: ``intensity`` is the axial intensity of a Lambertian disc (a surface at distance d,
    angle theta off the light's axis and facing it receives ``intensity * cos(theta) / d**2``,
    where irradiance 1 makes a white surface white), chosen so that a surface at the plant facing
    a light gets ``CEILING_IRRADIANCE`` or ``STAND_IRRADIANCE`` from it.
    """
    placed = place_plant(plant, cell, labels)
    if room is None:
        room = room_for(cell)
    mats = Materials()
    meshes = _room_meshes(room, mats)
    for ob in cell.obstacles:
        if has_visual(ob):
            meshes.extend(obstacle_meshes(ob, mats))
    if placed.points is None:
        meshes.append(placed.mesh)
    drawn = placed.drawn
    if len(drawn):
        lo, hi = drawn.min(axis=0), drawn.max(axis=0)
        target = (lo + hi) / 2
    else:
        target = soil_pose(cell)[:3, 3]
    lights, lamps = _lights(cell, room, target, mats)
    meshes.extend(lamps)
    for item in clutter_layout(room, pcg_seed, cell_keepouts(cell)):
        meshes.append(_CLUTTER_BUILDERS[item.kind](item, mats))
    return Scene(
        meshes=meshes, lights=lights, labels=placed.labels, plant="plant", points=placed.points, source=placed.source
    )


class Lab(interfaces.Room):
    """The paper's laboratory (the ``lab`` room): :func:`build_scene` for the run's cell, its
    clutter drawn from the run's ``pcg_seed``."""

    def scene(self, plant: Plant, *, seed: int, labels: str) -> Scene:
        return build_scene(self.cell, plant, pcg_seed=seed, labels=labels)
