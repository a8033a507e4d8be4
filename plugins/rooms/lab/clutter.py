"""The lab's floor plan: the room, and the paper's seeded clutter randomizer (section 3.3) that
places cabinets, pallets and drums around the cell. Pure geometry, no meshes: the same seed
gives the same layout."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from agrisim.robot.cell import Box, Cell, Cylinder
from agrisim.scene.transforms import translation, yaw_matrix

NOT_DRAWN = ("floor", "plant_keepout")
"""Obstacles without a visual of their own (the room's floor covers the physics floor)."""


def has_visual(ob: Box | Cylinder) -> bool:
    """Has ``ob`` a visual of its own? (Not in :data:`NOT_DRAWN`, a bench's ``plant_keepout_01``... neither.)"""
    return ob.name.rstrip("0123456789").removesuffix("_") not in NOT_DRAWN


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
        for x, y, yaw, var in zip(xs, ys, yaws, variants, strict=True):
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
        if not has_visual(ob):
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
