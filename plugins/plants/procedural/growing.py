"""What every procedural species grows with: organ ids and material slots, the
:class:`Grown` result, and small helpers for counts, texture tiles, orientations, tubes and
cards."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from agrisim.plugins.mesh_builder import MeshBuilder
from agrisim.scene.model import Label, LabelTable
from agrisim.scene.palette import BACKGROUND, PALETTE

from . import painters as P
from .optics import Leaf, aged_colour, chlorophyll_tints
from .shapes import direction, tubes, unit
from .textures import Atlas, Tile

LEAF, STEM, FLOWER = 1, 2, 3
FLOWER_WHITE, FLOWER_PURPLE = 3, 4

CARDS, STEMS, WOOD = 0, 1, 2  # material slots


def labels_for(*organs: str) -> LabelTable:
    """The label table of a species with these organs (ids in this order from 1)."""
    return LabelTable(
        [Label(0, "background", BACKGROUND)] + [Label(i + 1, n, PALETTE[n]) for i, n in enumerate(organs)]
    )


@dataclass
class Grown:
    """What a species' grower returns."""

    builder: MeshBuilder
    atlas: Atlas
    labels: LabelTable
    stem_colour: tuple[float, float, float]
    wood_colour: tuple[float, float, float] | None = None


def count(n: float, density: float) -> int:
    return max(1, round(n * density))


@dataclass(frozen=True)
class Ageing:
    """How a species' older leaves show their age: ``share`` of its leaf variants are aged,
    each yellowing in blotches up to ``yellowing`` of the way, with up to ``spots`` brown spots
    and a dried tip up to ``dry_tip`` of its length."""

    share: float = 0.0
    yellowing: float = 0.0
    spots: int = 0
    dry_tip: float = 0.0


@dataclass(frozen=True)
class Look:
    """A species' leaves beyond their shape: PROSPECT-D parameters (translucency and the
    colours of ageing), the upper side's roughness (the lower side's is ``back_roughness``),
    the lower side's colour against the upper's, ageing, and how much more chlorophyll than the
    palest (the painted one) a leaf may hold."""

    leaf: Leaf = Leaf()
    roughness: float = 0.4
    back_roughness: float = 0.75
    back_color: tuple[float, float, float] = (1.3, 1.2, 1.3)
    ageing: Ageing = Ageing()
    chlorophyll: float = 0.6
    """Each leaf holds 1 to 1 + ``chlorophyll`` times the palest leaf's chlorophyll (uniformly
    drawn): its own colour, as a vertex colour over the shared atlas."""

    def _tint_table(self) -> tuple[np.ndarray, np.ndarray]:
        grid = np.linspace(1.0, 1.0 + self.chlorophyll, 9)
        return grid, chlorophyll_tints(self.leaf, grid)

    def leaf_tints(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) linear vertex colours of ``n`` leaves, each its own draw of chlorophyll."""
        grid, table = self._tint_table()
        k = 1.0 + self.chlorophyll * rng.random(n)
        return np.column_stack([np.interp(k, grid, table[:, c]) for c in range(3)])

    def mean_tint(self) -> np.ndarray:
        """The leaves' expected vertex colour: the atlas paints the palest leaf as the painted
        colour divided by it, so that the average leaf keeps the colour painted."""
        _, table = self._tint_table()
        return (table[:-1] + table[1:]).mean(axis=0) / 2.0  # the trapezoid rule on the even grid

    def varied(self, painter: Callable, variant: int, variants: int, tex: np.random.Generator) -> Callable:
        """``painter`` as leaf variant ``variant`` of ``variants``: in its own shade (brightness
        and the balance of green and yellow, drawn from ``tex``), and aged when it is among the
        last ``share`` of them."""
        shade = 1.0 + tex.normal(0.0, 0.07)
        warm = tex.normal(0.0, 0.06)  # + toward yellow-green, - toward blue-green
        painter = P.tinted(painter, shade * np.array([1.0 + warm, 1.0, 1.0 - warm]))
        a = self.ageing
        if variant < variants - round(a.share * variants):
            return painter
        yellow = aged_colour(self.leaf, self.leaf.aged(green=0.2, brown=0.1))
        brown = aged_colour(self.leaf, self.leaf.aged(green=0.03, brown=1.5, water=0.3))
        return P.aged(painter, a.yellowing, a.spots, a.dry_tip, yellow, brown)


def tiles(
    atlas: Atlas,
    tex: np.random.Generator,
    k: int,
    height: float,
    aspect: float,
    make: Callable,
    look: Look | None = None,
) -> list[Tile]:
    """``k`` variants of a card texture, each ``height`` (fraction of the atlas) tall with
    width/length ``aspect``; ``make(i)`` returns the painter of variant ``i``; with ``look``
    (leaves) each has its own shade and the last of them age as the species does."""
    out = []
    for i in range(k):
        t = atlas.tile(height, height * aspect)
        painter = make(i) if look is None else look.varied(make(i), i, k, tex)
        out.append(atlas.paint(t, painter, tex))
    return out


def pick(geo: np.random.Generator, choices: list[Tile], n: int) -> np.ndarray:
    """Atlas rectangles (n x 4) of ``n`` cards, each a random variant."""
    rects = np.array([c.rect() for c in choices])
    return rects[geo.integers(0, len(choices), n)]


def azel(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(azimuth, elevation) of direction vectors (N x 3)."""
    d = unit(d)
    return np.arctan2(d[:, 1], d[:, 0]), np.arcsin(np.clip(d[:, 2], -1, 1))


def roll_towards(az: np.ndarray, elev: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    """The card roll that turns a card heading (az, elev) so that its across-axis follows
    ``lateral`` (projected)."""
    d = direction(az, elev)
    lat0 = np.stack([-np.sin(az), np.cos(az), np.zeros_like(az)], axis=-1)
    dxl = np.cross(d, lat0)
    return np.arctan2(np.sum(lateral * dxl, axis=1), np.sum(lateral * lat0, axis=1))


def curvature(
    geo: np.random.Generator,
    n: int,
    cup: tuple[float, float] = (0.0, 0.0),
    wave: tuple[float, float] = (0.0, 0.0),
    droop: tuple[float, float] | None = None,
) -> dict[str, np.ndarray]:
    """Per-leaf blade curvature for :func:`.shapes.strip_cards` and :func:`.shapes.plate_cards`,
    each leaf drawn within the species' ranges: ``cup`` (a trough across), ``wave`` (rippled
    margins, at a random phase) and, for plates, ``droop`` (the tip hanging)."""
    out = {"cup": geo.uniform(*cup, n), "wave": geo.uniform(*wave, n), "phase": geo.uniform(0.0, 2 * np.pi, n)}
    if droop is not None:
        out["droop"] = geo.uniform(*droop, n)
    return out


def golden_azimuths(geo: np.random.Generator, n: int, jitter: float = 0.35) -> np.ndarray:
    """Phyllotaxis: successive organs 137.5 degrees apart, jittered."""
    return geo.uniform(0, 2 * np.pi) + np.arange(n) * 2.39996 + geo.normal(0, jitter, n)


#: how thin a stem or petiole given one radius ends, against its base
TAPER = 0.65


def add_tubes(b: MeshBuilder, path: np.ndarray, radius, sides: int = 6, material: int = STEMS) -> None:
    """Stems along ``path`` (N x P x 3): ``radius`` per point (N x P or 1 x P), or one radius
    (scalar, or per stem) at the base tapering to :data:`TAPER` of it at the end."""
    path = np.asarray(path, float)
    if np.ndim(radius) <= 1:
        r = np.broadcast_to(np.asarray(radius, float).reshape(-1, 1), (len(path), 1))
        radius = r * np.linspace(1.0, TAPER, path.shape[1])[None]
    v, f = tubes(path, radius, sides)
    b.add(v, f, None, material, 0)


def add_cards(b: MeshBuilder, parts: tuple, material: int = CARDS, instance: bool = True) -> None:
    v, f, uv = parts[:3]
    b.add(v, f, uv, material, b.instances(len(v)) if instance else 0)


# ============================================================================ species


def plate_e2(normal: np.ndarray) -> np.ndarray:
    from .shapes import frame

    return frame(normal, np.zeros(len(normal)))[1]


def spin_towards(
    V: np.ndarray, pivot: np.ndarray, normal: np.ndarray, target: np.ndarray, anchor_dir: np.ndarray
) -> np.ndarray:
    """Rotate each item's vertices about ``normal`` through ``pivot`` so that ``anchor_dir``
    turns toward ``target`` (projected into the plane)."""
    nrm = unit(normal)
    tp = unit(target - np.sum(target * nrm, 1, keepdims=True) * nrm)
    ang = np.arctan2(np.sum(np.cross(anchor_dir, tp) * nrm, 1), np.sum(anchor_dir * tp, 1))
    c, s = np.cos(ang)[:, None, None], np.sin(ang)[:, None, None]
    r = V - pivot[:, None]
    k = nrm[:, None]
    rot = r * c + np.cross(np.broadcast_to(k, r.shape), r) * s + k * np.sum(k * r, -1, keepdims=True) * (1 - c)
    return pivot[:, None] + rot
