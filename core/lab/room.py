"""The lab around the robot cell as a :class:`agrisim.scene.model.Scene`: room, furniture, lights,
the seeded clutter randomizer of the paper (section 3.3), and the plant placed in its pot.

Backend-free (numpy only). Everything is built in world coordinates:

* a room (10 x 8 m, 3 m high by default, centred on the plant) with a tiled floor, painted
  walls with a skirting board and an acoustic-tile ceiling;
* the table, the pot and the robot stands drawn from :attr:`agrisim.scene.cell.Cell.obstacles`, with
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

import dataclasses
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from agrisim.lab import textures as tex
from agrisim.scene.cell import Box, Cell, Cylinder
from agrisim.scene.transforms import translation, yaw_matrix
from agrisim.scene.model import Label, LabelTable, Light, Material, Mesh, Plant, Scene

SOIL_INSET = 0.015
"""Depth of the soil surface below the pot's rim, m (capped at a third of the pot's height)."""
POT_WALL = 0.008
"""Thickness of the pot's wall seen at its rim, m (capped at a third of its radius)."""
POT_SEGMENTS = 48
"""Sides of the pot's polygon (a multiple of 4, so that its bounding box is the cylinder's)."""
DRUM_SEGMENTS = 24
CEILING_IRRADIANCE = 0.35
"""Irradiance each ceiling light gives the plant (1 = white on white), renderer-relative."""
STAND_IRRADIANCE = 0.3
"""Irradiance each stand lamp gives the plant's side facing it."""
PLANT_LABEL = Label(1, "plant", (0, 255, 0))
"""The single plant label of ``labels="plant"``."""
NOT_DRAWN = ("floor", "plant_keepout")
"""Obstacles without a visual of their own (the room's floor covers the physics floor)."""


# --------------------------------------------------------------------------------------------
# Room and clutter layout (pure geometry, no meshes)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Room:
    """The lab's box: floor ``size`` (x, y) centred on ``center``, ``height`` to the ceiling, and
    the ``clear`` middle rectangle where no clutter may be centred (the paper's 6 x 4 m)."""

    size: tuple[float, float] = (10.0, 8.0)
    height: float = 3.0
    center: tuple[float, float] = (0.0, 0.0)
    clear: tuple[float, float] = (6.0, 4.0)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the floor."""
        cx, cy = self.center
        hx, hy = self.size[0] / 2, self.size[1] / 2
        return cx - hx, cx + hx, cy - hy, cy + hy

    @property
    def floor_area(self) -> float:
        return self.size[0] * self.size[1]

    def in_clear(self, x: float, y: float) -> bool:
        """Is (x, y) strictly inside the middle rectangle kept free of clutter?"""
        return abs(x - self.center[0]) < self.clear[0] / 2 and abs(y - self.center[1]) < self.clear[1] / 2


@dataclass(frozen=True)
class ClutterKind:
    """One kind of clutter: its sampling rate and its footprint (``size`` full extents along its
    own x and y; round kinds have diameter ``size[0]``)."""

    name: str
    rate: float  # items per m^2 of floor
    size: tuple[float, float]
    height: float
    round: bool
    variants: int  # looks to choose from (colours, wood)


CLUTTER_KINDS: tuple[ClutterKind, ...] = (
    ClutterKind("cabinet", 0.10, (0.9, 0.5), 1.9, False, 3),  # steel double-door cabinet
    ClutterKind("pallet", 0.50, (1.2, 0.8), 0.144, False, 4),  # EUR pallet
    ClutterKind("drum", 0.75, (0.58, 0.58), 0.88, True, 4),  # 200 l steel drum
)
"""The paper's clutter, in priority order (earlier kinds win overlaps)."""
_KIND = {k.name: k for k in CLUTTER_KINDS}
_PRIORITY = {k.name: i for i, k in enumerate(CLUTTER_KINDS)}


@dataclass(frozen=True)
class Footprint:
    """A shape on the floor: a rectangle (half extents ``half`` along its own axes, turned by
    ``yaw``) or, when ``radius`` is set, a circle."""

    x: float
    y: float
    yaw: float = 0.0
    half: tuple[float, float] = (0.0, 0.0)
    radius: float | None = None

    def corners(self) -> np.ndarray:
        """4 x 2 corners of a rectangle, counter-clockwise."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        hx, hy = self.half
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        return local @ np.array([[c, s], [-s, c]]) + (self.x, self.y)

    def extent(self) -> tuple[float, float]:
        """Half extents of the axis-aligned box around the shape."""
        if self.radius is not None:
            return self.radius, self.radius
        c, s = abs(np.cos(self.yaw)), abs(np.sin(self.yaw))
        hx, hy = self.half
        return hx * c + hy * s, hx * s + hy * c


def _rects_overlap(a: Footprint, b: Footprint) -> bool:
    ca, cb = a.corners(), b.corners()
    for yaw in (a.yaw, b.yaw):  # separating axis test on both rectangles' edge normals
        for axis in ((np.cos(yaw), np.sin(yaw)), (-np.sin(yaw), np.cos(yaw))):
            pa, pb = ca @ axis, cb @ axis
            if pa.max() <= pb.min() or pb.max() <= pa.min():
                return False
    return True


def _rect_circle_overlap(r: Footprint, c: Footprint) -> bool:
    assert c.radius is not None
    d = np.array([c.x - r.x, c.y - r.y])
    co, si = np.cos(r.yaw), np.sin(r.yaw)
    local = np.array([co * d[0] + si * d[1], -si * d[0] + co * d[1]])
    nearest = np.clip(local, [-r.half[0], -r.half[1]], [r.half[0], r.half[1]])
    return float(np.hypot(*(local - nearest))) < c.radius


def overlap(a: Footprint, b: Footprint) -> bool:
    """Do two footprints share area (touching is not overlapping)?"""
    if a.radius is not None and b.radius is not None:
        return float(np.hypot(a.x - b.x, a.y - b.y)) < a.radius + b.radius
    if a.radius is not None:
        return _rect_circle_overlap(b, a)
    if b.radius is not None:
        return _rect_circle_overlap(a, b)
    return _rects_overlap(a, b)


@dataclass(frozen=True)
class Item:
    """One piece of clutter: ``kind`` (cabinet, pallet, drum), centre (x, y) on the floor, turn
    ``yaw`` about z in [0, pi) rad, which look (``variant``) and its position in the raw sample."""

    kind: str
    x: float
    y: float
    yaw: float
    variant: int = 0
    index: int = 0

    @property
    def spec(self) -> ClutterKind:
        return _KIND[self.kind]

    @property
    def priority(self) -> int:
        """0 is the highest (cabinets)."""
        return _PRIORITY[self.kind]

    @property
    def footprint(self) -> Footprint:
        k = self.spec
        if k.round:
            return Footprint(self.x, self.y, self.yaw, radius=k.size[0] / 2)
        return Footprint(self.x, self.y, self.yaw, half=(k.size[0] / 2, k.size[1] / 2))

    @property
    def world_T(self) -> np.ndarray:
        return translation(self.x, self.y, 0.0) @ yaw_matrix(self.yaw)


def sample_clutter(room: Room, seed: int) -> list[Item]:
    """The raw PCG sample: for each kind, a Poisson number of items (mean rate x floor area)
    uniform over the whole floor, with yaw ~ U(0, pi). Deterministic in ``seed``."""
    rng = np.random.default_rng(seed)
    xmin, xmax, ymin, ymax = room.bounds
    items: list[Item] = []
    for kind in CLUTTER_KINDS:
        n = int(rng.poisson(kind.rate * room.floor_area))
        xs = rng.uniform(xmin, xmax, n)
        ys = rng.uniform(ymin, ymax, n)
        yaws = rng.uniform(0.0, np.pi, n)
        variants = rng.integers(0, kind.variants, n)
        for x, y, yaw, var in zip(xs, ys, yaws, variants):
            items.append(Item(kind.name, float(x), float(y), float(yaw), int(var), len(items)))
    return items


def placeable(item: Item, room: Room, keepouts: Iterable[Footprint] = ()) -> bool:
    """May ``item`` stand here: centre outside the clear middle, wholly inside the walls, clear
    of the cell's furniture (``keepouts``)?"""
    if room.in_clear(item.x, item.y):
        return False
    fp = item.footprint
    ex, ey = fp.extent()
    xmin, xmax, ymin, ymax = room.bounds
    if item.x - ex < xmin or item.x + ex > xmax or item.y - ey < ymin or item.y + ey > ymax:
        return False
    return not any(overlap(fp, k) for k in keepouts)


def remove_overlaps(items: Sequence[Item]) -> list[Item]:
    """Keep items greedily in priority order (cabinet, pallet, drum; within a kind, sample
    order), dropping any that overlaps an item already kept. Result in that order."""
    kept: list[Item] = []
    for item in sorted(items, key=lambda it: it.priority):  # stable: sample order within a kind
        fp = item.footprint
        if not any(overlap(fp, k.footprint) for k in kept):
            kept.append(item)
    return kept


def clutter_layout(room: Room, seed: int, keepouts: Iterable[Footprint] = ()) -> list[Item]:
    """The paper's PCG layout: :func:`sample_clutter`, filtered by :func:`placeable`, then
    :func:`remove_overlaps`."""
    keepouts = list(keepouts)
    return remove_overlaps([it for it in sample_clutter(room, seed) if placeable(it, room, keepouts)])


def room_for(cell: Cell) -> Room:
    """The default lab room (10 x 8 x 3 m) centred on the cell's plant."""
    return Room(center=(float(cell.plant_center[0]), float(cell.plant_center[1])))


def _yaw_of(T: np.ndarray) -> float:
    return float(np.arctan2(T[1, 0], T[0, 0]))


def cell_keepouts(cell: Cell, margin: float = 0.1) -> list[Footprint]:
    """Footprints of the cell's furniture (stands, table, pot), grown by ``margin``: clutter stays
    off them whatever the cell's configuration."""
    out = []
    for ob in cell.obstacles:
        if ob.name in NOT_DRAWN:
            continue
        x, y = float(ob.world_T[0, 3]), float(ob.world_T[1, 3])
        if isinstance(ob, Cylinder):
            out.append(Footprint(x, y, radius=ob.radius + margin))
        else:
            out.append(Footprint(x, y, _yaw_of(ob.world_T), half=(ob.size[0] / 2 + margin, ob.size[1] / 2 + margin)))
    return out


def lab_layout(cell: Cell, pcg_seed: int = 42) -> tuple[Room, list[Item]]:
    """The room and clutter :func:`build_scene` uses for this cell and seed."""
    room = room_for(cell)
    return room, clutter_layout(room, pcg_seed, cell_keepouts(cell))


# --------------------------------------------------------------------------------------------
# Mesh primitives: (vertices, faces, uvs) with outward, counter-clockwise faces
# --------------------------------------------------------------------------------------------

Part = tuple[np.ndarray, np.ndarray, np.ndarray]


def _quad(center, a, b, uv_span=(1.0, 1.0), uv_offset=(0.0, 0.0)) -> Part:
    """Rectangle ``center +- a +- b`` (half vectors) facing ``a x b``; u runs along a, and the
    image's top edge is on the ``+b`` side."""
    c, a, b = (np.asarray(t, float) for t in (center, a, b))
    V = np.array([c - a - b, c + a - b, c + a + b, c - a + b])
    su, sv = uv_span
    u0, v0 = uv_offset
    UV = np.array([[u0, v0 + sv], [u0 + su, v0 + sv], [u0 + su, v0], [u0, v0]])
    return V, np.array([[0, 1, 2], [0, 2, 3]]), UV


_BOX_FACES = {  # name: (centre direction, a direction, b direction)
    "+x": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "-x": ((-1, 0, 0), (0, -1, 0), (0, 0, 1)),
    "+y": ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
    "-y": ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    "+z": ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
    "-z": ((0, 0, -1), (1, 0, 0), (0, -1, 0)),
}


def _box(
    size: Sequence[float],
    center: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    repeat: tuple[float, float] | None = (1.0, 1.0),
    skip: Iterable[str] = (),
    uv_offset: tuple[float, float] = (0.0, 0.0),
) -> dict[str, Part]:
    """The faces of a box of full extents ``size``, by name (+x, -x, ...). UVs repeat every
    ``repeat`` metres (u, v) or, with ``repeat=None``, fit each face to the whole texture."""
    h = np.asarray(size, float) / 2
    c0 = np.asarray(center, float)
    out = {}
    for name, (n, a, b) in _BOX_FACES.items():
        if name in skip:
            continue
        n, a, b = (np.asarray(t, float) * h for t in (n, a, b))
        la, lb = 2 * np.linalg.norm(a), 2 * np.linalg.norm(b)
        span = (1.0, 1.0) if repeat is None else (la / repeat[0], lb / repeat[1])
        out[name] = _quad(c0 + n, a, b, span, uv_offset)
    return out


def _ring(radius: float, n: int, seam: bool) -> np.ndarray:
    k = np.arange(n + 1 if seam else n)
    t = 2 * np.pi * k / n
    xy = radius * np.column_stack([np.cos(t), np.sin(t)])
    # exact extremes at 0, 90, 180, 270 deg so bounding boxes match the cylinder's
    if n % 4 == 0:
        quarter = k % (n // 4) == 0
        xy[quarter] = np.rint(xy[quarter] / radius) * radius
    return xy


def _cylinder_side(
    radius: float, z0: float, z1: float, n: int, *, inward: bool = False, u_repeats: float = 1.0
) -> Part:
    """The side of a z-aligned cylinder; u once (or ``u_repeats`` times) around, v from the top
    (0) to the bottom (1)."""
    xy = _ring(radius, n, seam=True)
    m = n + 1
    V = np.vstack([np.column_stack([xy, np.full(m, z0)]), np.column_stack([xy, np.full(m, z1)])])
    u = np.arange(m) / n * u_repeats
    UV = np.vstack([np.column_stack([u, np.ones(m)]), np.column_stack([u, np.zeros(m)])])
    k = np.arange(n)
    b, b1, t, t1 = k, k + 1, m + k, m + k + 1
    if inward:
        F = np.vstack([np.column_stack([b, t1, b1]), np.column_stack([b, t, t1])])
    else:
        F = np.vstack([np.column_stack([b, b1, t1]), np.column_stack([b, t1, t])])
    return V, F, UV


def _disc(radius: float, z: float, n: int, *, up: bool = True) -> Part:
    """A flat disc at height ``z`` facing +z (or -z); UVs map the disc's square to the texture."""
    xy = np.vstack([[0.0, 0.0], _ring(radius, n, seam=False)])
    V = np.column_stack([xy, np.full(n + 1, z)])
    UV = np.column_stack([0.5 + 0.5 * xy[:, 0] / radius, 0.5 - 0.5 * xy[:, 1] / radius])
    k = np.arange(n)
    F = np.column_stack([np.zeros(n, int), 1 + k, 1 + (k + 1) % n])
    if not up:
        F = F[:, [0, 2, 1]]
    return V, F, UV


def _annulus(r_in: float, r_out: float, z: float, n: int) -> Part:
    """A flat ring at height ``z`` facing +z; planar UVs over the outer disc's square."""
    outer, inner = _ring(r_out, n, seam=False), _ring(r_in, n, seam=False)
    xy = np.vstack([outer, inner])
    V = np.column_stack([xy, np.full(2 * n, z)])
    UV = np.column_stack([0.5 + 0.5 * xy[:, 0] / r_out, 0.5 - 0.5 * xy[:, 1] / r_out])
    k = np.arange(n)
    o, o1, i, i1 = k, (k + 1) % n, n + k, n + (k + 1) % n
    F = np.vstack([np.column_stack([o, o1, i1]), np.column_stack([o, i1, i])])
    return V, F, UV


class _MeshBuilder:
    """Collects parts (each with a material and a local pose) into one :class:`Mesh`."""

    def __init__(self) -> None:
        self.V: list[np.ndarray] = []
        self.F: list[np.ndarray] = []
        self.UV: list[np.ndarray] = []
        self.FM: list[np.ndarray] = []
        self.materials: list[Material] = []
        self.count = 0

    def add(self, part: Part, material: Material, T: np.ndarray | None = None) -> None:
        V, F, UV = part
        if T is not None:
            V = V @ T[:3, :3].T + T[:3, 3]
        idx = next((i for i, m in enumerate(self.materials) if m is material), None)
        if idx is None:
            idx = len(self.materials)
            self.materials.append(material)
        self.V.append(V)
        self.F.append(F + self.count)
        self.UV.append(UV)
        self.FM.append(np.full(len(F), idx))
        self.count += len(V)

    def add_all(self, parts: Iterable[Part], material: Material, T: np.ndarray | None = None) -> None:
        for p in parts:
            self.add(p, material, T)

    def build(self, name: str, T: np.ndarray | None = None) -> Mesh:
        V = np.vstack(self.V)
        if T is not None:
            V = V @ T[:3, :3].T + T[:3, 3]
        return Mesh(name, V, np.vstack(self.F), self.materials, np.concatenate(self.FM), np.vstack(self.UV))


# --------------------------------------------------------------------------------------------
# Materials
# --------------------------------------------------------------------------------------------

CABINET_COLORS = ((0.56, 0.58, 0.61), (0.30, 0.40, 0.55), (0.80, 0.76, 0.66))
DRUM_COLORS = ((0.10, 0.24, 0.58), (0.62, 0.11, 0.09), (0.14, 0.40, 0.20), (0.86, 0.62, 0.08))


class _Materials:
    """One :class:`Material` per look, made on first use and shared by the meshes of a scene."""

    def __init__(self) -> None:
        self._cache: dict[tuple, Material] = {}

    def get(self, key: tuple, make) -> Material:
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def textured(self, name: str, albedo: np.ndarray, color=(1.0, 1.0, 1.0, 1.0)) -> Material:
        return self.get((name, color), lambda: Material(name, color=color, albedo=albedo))


# --------------------------------------------------------------------------------------------
# Scene parts
# --------------------------------------------------------------------------------------------


def _room_meshes(room: Room, mats: _Materials) -> list[Mesh]:
    cx, cy = room.center
    hx, hy, H = room.size[0] / 2, room.size[1] / 2, room.height
    floor = _MeshBuilder()
    tiles = mats.textured("floor_tiles", tex.floor_tiles())
    floor.add(_quad((cx, cy, 0.0), (hx, 0, 0), (0, hy, 0), (2 * hx / 2.4, 2 * hy / 2.4)), tiles)
    ceiling = _MeshBuilder()
    ceiling.add(
        _quad((cx, cy, H), (hx, 0, 0), (0, -hy, 0), (2 * hx / 1.2, 2 * hy / 1.2)),
        mats.textured("ceiling_tiles", tex.ceiling_tiles()),
    )
    walls = _MeshBuilder()
    paint = mats.textured("wall_paint", tex.wall_paint())
    for nx, ny, half in ((0, 1, hx), (0, -1, hx), (1, 0, hy), (-1, 0, hy)):
        inward = np.array([nx, ny, 0.0])
        centre = np.array([cx, cy, H / 2]) - inward * np.array([hx, hy, 0.0])
        a = np.cross([0.0, 0.0, 1.0], inward) * half  # a x b = inward
        walls.add(_quad(centre, a, (0, 0, H / 2), (2 * half / 2.0, 1.0)), paint)
    return [floor.build("floor"), walls.build("walls"), ceiling.build("ceiling")]


def _obstacle_mesh(ob: Box | Cylinder, mats: _Materials) -> list[Mesh]:
    b = _MeshBuilder()
    if isinstance(ob, Cylinder) and ob.name == "pot":
        r, h = ob.radius, ob.height
        wall, inset = min(POT_WALL, r / 3), min(SOIL_INSET, h / 3)
        clay = mats.textured("terracotta", tex.terracotta())
        inner = mats.textured("terracotta_inner", tex.terracotta(), (0.62, 0.62, 0.62, 1.0))
        b.add(_cylinder_side(r, -h / 2, h / 2, POT_SEGMENTS, u_repeats=2.0), clay)
        b.add(_annulus(r - wall, r, h / 2, POT_SEGMENTS), clay)
        b.add(_cylinder_side(r - wall, h / 2 - inset, h / 2, POT_SEGMENTS, inward=True, u_repeats=2.0), inner)
        soil = _MeshBuilder()
        soil.add(_disc(r - wall, h / 2 - inset, POT_SEGMENTS), mats.textured("soil", tex.soil()))
        return [b.build(ob.name, ob.world_T), soil.build("soil", ob.world_T)]
    if isinstance(ob, Cylinder):
        metal = mats.textured("metal_light", tex.painted_metal((0.7, 0.7, 0.72), 1))
        b.add(_cylinder_side(ob.radius, -ob.height / 2, ob.height / 2, POT_SEGMENTS), metal)
        b.add(_disc(ob.radius, ob.height / 2, POT_SEGMENTS), metal)
        b.add(_disc(ob.radius, -ob.height / 2, POT_SEGMENTS, up=False), metal)
        return [b.build(ob.name, ob.world_T)]
    on_floor = abs(ob.world_T[2, 3] - ob.size[2] / 2) < 1e-9
    faces = _box(ob.size, skip=("-z",) if on_floor else ())
    if ob.name == "table":
        top = mats.textured("laminate", tex.laminate())
        side = mats.textured("table_side", tex.painted_metal((0.84, 0.85, 0.87), 2))
        for name, part in faces.items():
            b.add(part, top if name == "+z" else side)
    else:  # stands and anything else: dark powder-coated steel
        b.add_all(faces.values(), mats.textured("stand_metal", tex.painted_metal((0.27, 0.28, 0.30), 3)))
    return [b.build(ob.name, ob.world_T)]


def _cabinet(item: Item, mats: _Materials) -> Mesh:
    k = item.spec
    color = CABINET_COLORS[item.variant % len(CABINET_COLORS)]
    size = (k.size[0], k.size[1], k.height)
    faces = _box(size, (0, 0, k.height / 2), skip=("-z",))
    front = _box(size, (0, 0, k.height / 2), repeat=None)["-y"]
    b = _MeshBuilder()
    body = mats.textured(f"cabinet_body_{item.variant}", tex.painted_metal(color, 10 + item.variant))
    for name, part in faces.items():
        if name == "-y":
            b.add(front, mats.textured(f"cabinet_front_{item.variant}", tex.cabinet_front(color)))
        else:
            b.add(part, body)
    return b.build(f"cabinet_{item.index:03d}", item.world_T)


def _pallet(item: Item, mats: _Materials) -> Mesh:
    """An EUR pallet (1.2 x 0.8 x 0.144 m) of real slats: 3 bottom boards, 9 blocks, 3 cross
    boards, 5 top deck boards."""
    wood = mats.textured(f"pallet_wood_{item.variant}", tex.wood(item.variant))
    rng = np.random.default_rng([item.variant, 77])  # boards differ, pallets of a variant agree
    b = _MeshBuilder()
    t = 0.022
    rot = yaw_matrix(np.pi / 2)

    def board(length: float, width: float, height: float, x: float, y: float, z: float, across: bool = False) -> None:
        offset = (float(rng.random()), float(rng.random()))
        faces = _box((length, width, height), repeat=(1.0, 0.25), skip=("-z",), uv_offset=offset)
        T = translation(x, y, z + height / 2) @ (rot if across else np.eye(4))
        b.add_all(faces.values(), wood, T)

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
    return b.build(f"pallet_{item.index:03d}", item.world_T)


def _drum(item: Item, mats: _Materials) -> Mesh:
    k = item.spec
    color = DRUM_COLORS[item.variant % len(DRUM_COLORS)]
    r = k.size[0] / 2
    b = _MeshBuilder()
    side = mats.textured(f"drum_side_{item.variant}", tex.drum_side(color))
    b.add(_cylinder_side(r, 0.0, k.height, DRUM_SEGMENTS), side)
    b.add(_disc(r, k.height, DRUM_SEGMENTS), mats.textured(f"drum_lid_{item.variant}", tex.drum_lid(color)))
    return b.build(f"drum_{item.index:03d}", item.world_T)


_CLUTTER_BUILDERS = {"cabinet": _cabinet, "pallet": _pallet, "drum": _drum}


def _plant_mesh(plant: Plant, world_T_plant: np.ndarray, labels: str) -> tuple[Mesh, LabelTable]:
    mesh = plant.mesh
    if labels == "plant":
        lut = np.ones(256, np.uint8)
        lut[0] = 0
        materials = [
            dataclasses.replace(m, labels=None if m.labels is None else lut[m.labels], label=int(lut[m.label]))
            for m in mesh.materials
        ]
        table = LabelTable([Label(0, "background", (0, 0, 0)), PLANT_LABEL])
    else:
        materials = list(mesh.materials)
        table = LabelTable(list(plant.labels.labels))
    V = mesh.vertices @ world_T_plant[:3, :3].T + world_T_plant[:3, 3]
    out = Mesh("plant", V, mesh.faces, materials, mesh.face_material, mesh.uvs, mesh.face_instance)
    return out, table


def soil_pose(cell: Cell) -> np.ndarray:
    """``world_T_plant``: the plant frame on the soil surface (centre of the pot, z up)."""
    pot = next((ob for ob in cell.obstacles if ob.name == "pot"), None)
    if pot is None:
        return translation(*cell.plant_center)
    assert isinstance(pot, Cylinder)
    return pot.world_T @ translation(0.0, 0.0, pot.height / 2 - min(SOIL_INSET, pot.height / 3))


def _intensity(irradiance: float, position: np.ndarray, direction: np.ndarray, target: np.ndarray) -> float:
    """Axial intensity giving ``irradiance`` at ``target`` (facing the light): E = I cos / d^2."""
    d = target - position
    dist = float(np.linalg.norm(d))
    cos = max(float(np.dot(direction, d / dist)), 0.2)
    return irradiance * dist**2 / cos


def _lights(cell: Cell, room: Room, target: np.ndarray, mats: _Materials) -> tuple[list[Light], list[Mesh]]:
    """Two ceiling panels facing down either side of the plant (along y, clear of the arms) and a
    lamp on each robot stand's inner edge facing the plant."""
    lights: list[Light] = []
    meshes: list[Mesh] = []
    panel = mats.get(("lamp_panel",), lambda: Material("lamp_panel", color=(1.0, 1.0, 1.0, 1.0)))
    radius = 0.3
    for i, side in enumerate((1.0, -1.0), start=1):
        pos = np.array([target[0], target[1] + 0.9 * side, room.height - 0.02])
        down = np.array([0.0, 0.0, -1.0])
        lights.append(
            Light(
                f"ceiling_{i}", "area", pos, down, (1.0, 0.97, 0.92), _intensity(CEILING_IRRADIANCE, pos, down, target), radius
            )
        )
        b = _MeshBuilder()
        b.add(_disc(radius, 0.0, 24, up=False), panel, translation(pos[0], pos[1], room.height - 0.004))
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
    if labels not in ("plant", "organs"):
        raise ValueError(f"labels must be 'plant' or 'organs', got {labels!r}")
    if room is None:
        room = room_for(cell)
    mats = _Materials()
    meshes = _room_meshes(room, mats)
    for ob in cell.obstacles:
        if ob.name not in NOT_DRAWN:
            meshes.extend(_obstacle_mesh(ob, mats))
    plant_mesh, table = _plant_mesh(plant, soil_pose(cell), labels)
    meshes.append(plant_mesh)
    if len(plant_mesh.vertices):
        lo, hi = plant_mesh.vertices.min(axis=0), plant_mesh.vertices.max(axis=0)
        target = (lo + hi) / 2
    else:
        target = soil_pose(cell)[:3, 3]
    lights, lamps = _lights(cell, room, target, mats)
    meshes.extend(lamps)
    for item in clutter_layout(room, pcg_seed, cell_keepouts(cell)):
        meshes.append(_CLUTTER_BUILDERS[item.kind](item, mats))
    return Scene(meshes=meshes, lights=lights, labels=table, plant="plant")
