"""The ten procedural species standing in for the paper's Megascans plants (Table 1).

Each ``grow_<species>(geo, tex, size, density)`` returns a :class:`Grown`: the mesh parts (one
:class:`.geometry.MeshBuilder`), the species' texture atlas and its label table, in the plant
frame (origin at the centre of the soil surface, z up, metres). ``geo`` and ``tex`` are the
random generators for geometry and textures; ``size`` is the atlas size in pixels; ``density``
multiplies the number of leaves, fronds, blades and flowers.

Like artists' assets, leaves, fronds and blades are alpha-tested cards (RGBA atlas, alpha carries
the outline) with a label texture at the same UVs, stems are opaque tubes, and the boxwood is a
dense ball of small *solid* leaves that barely relies on opacity. How much of each plant's area
its opacity cuts away spans the range the paper measured (Table 2): boxwood ~0, ferns and
basket grass more than half.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from agrisim.scene.model import Label, LabelTable

from agrisim.scene.palette import BACKGROUND, PALETTE

from . import painters as P
from .shapes import MeshBuilder, bezier, direction, plate_cards, solid_leaves, strip_cards, tubes, unit
from .textures import Atlas, Tile

LEAF, STEM, FLOWER = 1, 2, 3
FLOWER_WHITE, FLOWER_PURPLE = 3, 4

CARDS, STEMS, WOOD = 0, 1, 2  # material slots


def labels_for(*organs: str) -> LabelTable:
    """The label table of a species with these organs (ids in this order from 1)."""
    return LabelTable([Label(0, "background", BACKGROUND)] + [Label(i + 1, n, PALETTE[n]) for i, n in enumerate(organs)])


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


def tiles(atlas: Atlas, tex: np.random.Generator, k: int, height: float, aspect: float, make: Callable) -> list[Tile]:
    """``k`` variants of a card texture, each ``height`` (fraction of the atlas) tall with
    width/length ``aspect``; ``make(i)`` returns the painter of variant ``i``."""
    out = []
    for i in range(k):
        t = atlas.tile(height, height * aspect)
        out.append(atlas.paint(t, make(i), tex))
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


def golden_azimuths(geo: np.random.Generator, n: int, jitter: float = 0.35) -> np.ndarray:
    """Phyllotaxis: successive organs 137.5 degrees apart, jittered."""
    return geo.uniform(0, 2 * np.pi) + np.arange(n) * 2.39996 + geo.normal(0, jitter, n)


def add_tubes(b: MeshBuilder, path: np.ndarray, radius, sides: int = 6, material: int = STEMS) -> None:
    v, f = tubes(path, radius, sides)
    b.add(v, f, None, material, 0)


def add_cards(b: MeshBuilder, parts: tuple, material: int = CARDS, instance: bool = True) -> None:
    v, f, uv = parts[:3]
    b.add(v, f, uv, material, b.instances(len(v)) if instance else 0)


# ============================================================================ species


def grow_indian_cress(geo, tex, size, density) -> Grown:
    """Nasturtium (Tropaeolum majus): ~0.2 m, round peltate leaves on long petioles from a few
    sprawling stems, orange five-petalled flowers."""
    atlas = Atlas(size)
    col = {"base": (0.33, 0.52, 0.22), "light": (0.5, 0.66, 0.33), "dark": (0.2, 0.36, 0.13), "vein": (0.72, 0.8, 0.55)}
    leaf_t = tiles(atlas, tex, 6, 0.3, 1.0, lambda i: P.peltate(LEAF, col))
    fcols = [
        {
            "base": (0.95, 0.45, 0.05),
            "light": (1.0, 0.62, 0.1),
            "dark": (0.85, 0.25, 0.02),
            "inner": (1.0, 0.8, 0.1),
            "guides": (0.6, 0.05, 0.02),
            "disc": (0.9, 0.7, 0.2),
        },
        {
            "base": (0.88, 0.12, 0.05),
            "light": (0.98, 0.3, 0.08),
            "dark": (0.7, 0.05, 0.03),
            "inner": (1.0, 0.7, 0.1),
            "guides": (0.4, 0.02, 0.02),
            "disc": (0.9, 0.7, 0.2),
        },
        {
            "base": (1.0, 0.75, 0.1),
            "light": (1.0, 0.85, 0.3),
            "dark": (0.95, 0.55, 0.05),
            "inner": (1.0, 0.5, 0.05),
            "guides": (0.7, 0.15, 0.02),
            "disc": (0.9, 0.7, 0.2),
        },
    ]
    flower_t = tiles(
        atlas, tex, 3, 0.2, 1.0, lambda i: P.radial_flower(FLOWER, fcols[i], 5, petal_width=0.8, centre=0.12)
    )
    b = MeshBuilder()
    # sprawling stems
    ns = count(geo.integers(3, 6), min(density, 1.5))
    az = golden_azimuths(geo, ns, 0.5)
    reach = geo.uniform(0.07, 0.15, ns)
    top = geo.uniform(0.06, 0.12, ns)
    p0 = np.column_stack([0.01 * np.cos(az), 0.01 * np.sin(az), np.full(ns, -0.005)])
    dirs = np.column_stack([np.cos(az), np.sin(az), np.zeros(ns)])
    p3 = p0 + dirs * reach[:, None] + np.column_stack([np.zeros((ns, 2)), top])
    p1 = p0 + np.array([0, 0, 0.05])
    p2 = p3 - dirs * 0.04 + np.array([0, 0, 0.01])
    stems = bezier(p0, p1, p2, p3, 8)
    add_tubes(b, stems, np.linspace(0.0032, 0.002, 8)[None].repeat(ns, 0), 6)
    # leaves on petioles from points along the stems
    nl = count(geo.integers(16, 24), density)
    which = geo.integers(0, ns, nl)
    u = geo.uniform(0.15, 1.0, nl)
    idx = np.minimum((u * 7).astype(int), 6)
    frac = (u * 7 - idx)[:, None]
    attach = stems[which, idx] * (1 - frac) + stems[which, idx + 1] * frac
    laz = np.arctan2(attach[:, 1], attach[:, 0]) + geo.normal(0, 0.6, nl)
    rad = np.clip(np.hypot(attach[:, 0], attach[:, 1]) + geo.uniform(0.0, 0.08, nl), 0.04, 0.21)
    height = np.clip(0.2 - 0.45 * rad + geo.normal(0, 0.025, nl), attach[:, 2] + 0.03, 0.21)
    centre = np.column_stack([rad * np.cos(laz), rad * np.sin(laz), height])
    diam = geo.uniform(0.04, 0.075, nl) * (1.1 - 0.5 * rad)
    tilt = geo.uniform(0.0, 0.5, nl)
    normal = np.column_stack([np.sin(tilt) * np.cos(laz), np.sin(tilt) * np.sin(laz), np.cos(tilt)])
    c1 = attach + np.array([0, 0, 0.04])
    c2 = centre - normal * 0.04
    add_tubes(b, bezier(attach, c1, c2, centre - normal * 0.002, 7), 0.0014, 5)
    add_cards(
        b,
        plate_cards(
            centre, normal, geo.uniform(0, 2 * np.pi, nl), diam, pick(geo, leaf_t, nl), size, cup=-0.06, corner=0.92
        ),
    )
    # flowers on pedicels, facing out and up
    nf = count(geo.integers(3, 7), density)
    which = geo.integers(0, ns, nf)
    attach = stems[which, geo.integers(3, 8, nf)]
    faz = np.arctan2(attach[:, 1], attach[:, 0]) + geo.normal(0, 0.5, nf)
    frad = np.clip(np.hypot(attach[:, 0], attach[:, 1]) + geo.uniform(0.02, 0.06, nf), 0.05, 0.22)
    fpos = np.column_stack(
        [frad * np.cos(faz), frad * np.sin(faz), np.clip(attach[:, 2] + geo.uniform(0.02, 0.06, nf), 0.05, 0.2)]
    )
    tilt = geo.uniform(0.6, 1.2, nf)
    fn = np.column_stack([np.sin(tilt) * np.cos(faz), np.sin(tilt) * np.sin(faz), np.cos(tilt)])
    add_tubes(b, bezier(attach, attach + [0, 0, 0.03], fpos - fn * 0.03, fpos - fn * 0.004, 6), 0.0011, 5)
    add_cards(
        b,
        plate_cards(
            fpos, fn, geo.uniform(0, 6.3, nf), geo.uniform(0.04, 0.055, nf), pick(geo, flower_t, nf), size, cup=0.12
        ),
        instance=False,
    )
    return Grown(b, atlas, labels_for("leaf", "stem", "flower"), (0.42, 0.58, 0.24))


def grow_boston_fern(geo, tex, size, density) -> Grown:
    """Boston fern (Nephrolepis exaltata): many long, narrow, once-pinnate fronds arching out
    of a central crown."""
    atlas = Atlas(size)
    col = {
        "base": (0.3, 0.55, 0.16),
        "light": (0.5, 0.72, 0.26),
        "dark": (0.16, 0.36, 0.08),
        "vein": (0.55, 0.7, 0.3),
        "rachis": (0.35, 0.45, 0.18),
    }
    aspect = 0.17
    env = lambda Y: np.sin(np.pi * np.clip(Y, 0, 1) ** 0.5) ** 0.4
    frond_t = tiles(
        atlas,
        tex,
        5,
        0.94,
        aspect,
        lambda i: P.frond(LEAF, col, pinnae=34 + 2 * i, envelope=env, pinna_width=0.46, angle=0.3, stipe=0.07),
    )
    b = MeshBuilder()
    n = count(geo.integers(34, 44), density)
    az = golden_azimuths(geo, n, 0.3)
    r0 = geo.uniform(0.004, 0.018, n)
    base = np.column_stack([r0 * np.cos(az), r0 * np.sin(az), np.full(n, 0.01)])
    elev = geo.uniform(0.75, 1.45, n)
    length = geo.uniform(0.22, 0.32, n)
    bend = geo.uniform(1.3, 2.3, n) * (elev / 1.2)
    V, F, UV, C = strip_cards(
        base,
        az,
        elev,
        length,
        pick(geo, frond_t, n),
        size,
        segments=10,
        bend=bend,
        bend_power=1.4,
        curl=geo.normal(0, 0.25, n),
        twist=geo.normal(0, 0.4, n),
        fold=0.12,
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    stipe = np.linspace(0, 1, 4)
    seg = 1.0 / 10
    path = C[:, 0][:, None] + (C[:, 1] - C[:, 0])[:, None] * (stipe * 0.07 / seg)[None, :, None]
    path[:, 0, 2] = -0.004
    add_tubes(b, path, 0.0016, 5)
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.3, 0.35, 0.15))


def grow_amaryllis(geo, tex, size, density) -> Grown:
    """Amaryllis (Hippeastrum): a bulb with long arching strap leaves and a tall hollow scape
    carrying big red trumpet flowers."""
    atlas = Atlas(size)
    col = {"base": (0.2, 0.45, 0.14), "light": (0.32, 0.58, 0.2), "dark": (0.12, 0.32, 0.08), "vein": (0.35, 0.6, 0.25)}
    leaf_t = tiles(
        atlas,
        tex,
        4,
        0.95,
        0.1,
        lambda i: P.lamina(
            P.strap(0.12, 0.45),
            col["base"],
            col["light"],
            col["dark"],
            col["vein"],
            LEAF,
            parallel=0.008,
            midrib=0.004,
            vein_width=0.002,
            vein_strength=0.4,
        ),
    )
    pcol = [
        {
            "base": (0.78, 0.05, 0.07),
            "light": (0.92, 0.18, 0.14),
            "dark": (0.55, 0.02, 0.04),
            "stripe": (0.97, 0.9, 0.85),
            "throat": (0.55, 0.65, 0.3),
        },
        {
            "base": (0.85, 0.1, 0.1),
            "light": (0.95, 0.3, 0.2),
            "dark": (0.6, 0.03, 0.05),
            "stripe": (1.0, 0.95, 0.9),
            "throat": (0.5, 0.62, 0.28),
        },
    ]
    tepal_t = tiles(atlas, tex, 4, 0.3, 0.42, lambda i: P.petal(FLOWER, pcol[i % 2], P.ovate(0.6, 1.1)))
    b = MeshBuilder()
    # bulb (opaque, brown) and the leaves from its neck
    zb = np.array([-0.01, 0.0, 0.012, 0.025, 0.036, 0.045])
    rb = np.array([0.026, 0.034, 0.035, 0.028, 0.016, 0.01])
    bulb = np.column_stack([np.zeros(6), np.zeros(6), zb])[None]
    add_tubes(b, bulb, rb[None], 12, WOOD)
    n = count(geo.integers(5, 9), density)
    az = golden_azimuths(geo, n, 0.25)
    r0 = 0.008
    base = np.column_stack([r0 * np.cos(az), r0 * np.sin(az), np.full(n, 0.035)])
    elev = geo.uniform(0.95, 1.35, n)
    V, F, UV, _ = strip_cards(
        base,
        az,
        elev,
        geo.uniform(0.26, 0.34, n),
        pick(geo, leaf_t, n),
        size,
        segments=10,
        bend=geo.uniform(1.3, 2.0, n),
        bend_power=1.6,
        fold=0.3,
        twist=geo.normal(0, 0.5, n),
        curl=geo.normal(0, 0.2, n),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    # scape
    lean = geo.uniform(0, 2 * np.pi)
    top = np.array([0.03 * np.cos(lean), 0.03 * np.sin(lean), geo.uniform(0.3, 0.34)])
    scape = bezier(np.array([[0, 0, 0.03]]), np.array([[0, 0, 0.15]]), (top - [0, 0, 0.08])[None], top[None], 8)
    add_tubes(b, scape, np.linspace(0.0065, 0.0048, 8)[None], 8)
    # flowers: trumpets of six tepals around pedicels pointing out and slightly up
    nf = int(geo.integers(2, 5))
    faz = geo.uniform(0, 2 * np.pi) + np.arange(nf) * 2 * np.pi / nf + geo.normal(0, 0.2, nf)
    fel = geo.uniform(-0.1, 0.35, nf)
    axis = direction(faz, fel)
    ped_end = top + axis * 0.035
    add_tubes(
        b,
        bezier(np.repeat(top[None], nf, 0), top + axis * 0.012 + [0, 0, 0.01], ped_end - axis * 0.01, ped_end, 5),
        0.0025,
        6,
    )
    k = np.arange(6)
    a = axis.repeat(6, 0)
    ref = np.where(np.abs(a[:, 2:3]) > 0.9, np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))
    e1 = unit(np.cross(a, ref))
    e2 = np.cross(a, e1)
    ang = np.tile(k * np.pi / 3, nf) + np.repeat(geo.uniform(0, 1, nf), 6)
    radial = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
    spread = geo.uniform(0.5, 0.65, 6 * nf)
    d = np.cos(spread)[:, None] * a + np.sin(spread)[:, None] * radial
    taz, tel = azel(d)
    lat = unit(np.cross(a, d))
    roll = roll_towards(taz, tel, lat)
    base = ped_end.repeat(6, 0) + radial * 0.004
    V, F, UV, _ = strip_cards(
        base,
        taz,
        tel,
        geo.uniform(0.07, 0.09, 6 * nf),
        pick(geo, tepal_t, 6 * nf),
        size,
        segments=4,
        roll=roll,
        fold=-0.25,
    )
    b.add(V, F, UV, CARDS, 0)
    return Grown(b, atlas, labels_for("leaf", "stem", "flower"), (0.3, 0.5, 0.2), wood_colour=(0.55, 0.4, 0.25))


def grow_bog_marshcress(geo, tex, size, density) -> Grown:
    """Bog marshcress (Rorippa palustris): a small rosette of deeply lobed leaves with a couple
    of short branched stems bearing tiny yellow flowers."""
    atlas = Atlas(size)
    col = {
        "base": (0.3, 0.5, 0.18),
        "light": (0.45, 0.64, 0.26),
        "dark": (0.18, 0.33, 0.1),
        "vein": (0.55, 0.68, 0.35),
        "tint": (0.45, 0.3, 0.22),
    }
    leaf_t = tiles(atlas, tex, 5, 0.48, 0.5, lambda i: P.lobed(LEAF, col, lobes=3.5 + 0.5 * (i % 3)))
    fcol = {
        "base": (0.98, 0.88, 0.2),
        "light": (1.0, 0.95, 0.45),
        "dark": (0.9, 0.75, 0.1),
        "inner": (0.85, 0.8, 0.25),
        "disc": (0.7, 0.7, 0.25),
    }
    flower_t = tiles(atlas, tex, 2, 0.12, 1.0, lambda i: P.radial_flower(FLOWER, fcol, 4, petal_width=0.7, centre=0.15))
    b = MeshBuilder()
    n = count(geo.integers(11, 17), density)
    az = golden_azimuths(geo, n, 0.2)
    base = np.column_stack([0.005 * np.cos(az), 0.005 * np.sin(az), np.full(n, 0.005)])
    V, F, UV, _C = strip_cards(
        base,
        az,
        geo.uniform(0.25, 0.8, n),
        geo.uniform(0.07, 0.12, n),
        pick(geo, leaf_t, n),
        size,
        segments=4,
        bend=geo.uniform(0.3, 0.8, n),
        fold=0.15,
        twist=geo.normal(0, 0.3, n),
        curl=geo.normal(0, 0.3, n),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    # flowering stems with a few stem leaves and racemes of tiny flowers
    ns = int(geo.integers(1, 4))
    saz = geo.uniform(0, 2 * np.pi, ns)
    tops = np.column_stack([0.04 * np.cos(saz), 0.04 * np.sin(saz), geo.uniform(0.1, 0.16, ns)])
    p0 = np.zeros((ns, 3))
    stems = bezier(p0, p0 + [0, 0, 0.05], tops - [0, 0, 0.04], tops, 7)
    add_tubes(b, stems, 0.0016, 5)
    nsl = 3 * ns
    at = stems[np.repeat(np.arange(ns), 3), np.tile([2, 3, 4], ns)]
    sl_az = geo.uniform(0, 2 * np.pi, nsl)
    V, F, UV, _ = strip_cards(
        at,
        sl_az,
        geo.uniform(0.2, 0.7, nsl),
        geo.uniform(0.03, 0.05, nsl),
        pick(geo, leaf_t, nsl),
        size,
        segments=2,
        bend=0.4,
        fold=0.1,
    )
    b.add(V, F, UV, CARDS, b.instances(nsl))
    nfl = 9 * ns
    centre = tops.repeat(9, 0) + geo.normal(0, 0.012, (nfl, 3)) * [1, 1, 0.6]
    normal = unit(centre - tops.repeat(9, 0) + [0, 0, 0.02])
    add_tubes(b, np.stack([tops.repeat(9, 0), centre], axis=1), 0.0007, 4)
    add_cards(
        b,
        plate_cards(
            centre,
            normal,
            geo.uniform(0, 6.3, nfl),
            geo.uniform(0.008, 0.012, nfl),
            pick(geo, flower_t, nfl),
            size,
            cup=0.1,
            cells=1,
        ),
        instance=False,
    )
    return Grown(b, atlas, labels_for("leaf", "stem", "flower"), (0.36, 0.45, 0.2))


def grow_chinese_evergreen(geo, tex, size, density) -> Grown:
    """Chinese evergreen (Aglaonema): broad, silver-patterned lanceolate leaves on sheathing
    petioles around a few short, thick canes."""
    atlas = Atlas(size)
    col = {
        "base": (0.13, 0.32, 0.13),
        "light": (0.2, 0.42, 0.18),
        "dark": (0.08, 0.22, 0.08),
        "vein": (0.3, 0.45, 0.25),
    }
    leaf_t = tiles(
        atlas,
        tex,
        4,
        0.48,
        0.42,
        lambda i: P.lamina(
            P.ovate(0.42, 0.95),
            col["base"],
            col["light"],
            col["dark"],
            col["vein"],
            LEAF,
            vein_spacing=0.06,
            vein_slope=0.9,
            midrib=0.008,
            pattern=P.aglaonema_pattern,
        ),
    )
    b = MeshBuilder()
    nc = int(geo.integers(2, 4))
    caz = geo.uniform(0, 2 * np.pi, nc)
    ctop = np.column_stack([0.02 * np.cos(caz), 0.02 * np.sin(caz), geo.uniform(0.04, 0.09, nc)])
    canes = bezier(
        np.column_stack([0.01 * np.cos(caz), 0.01 * np.sin(caz), np.full(nc, -0.005)]),
        ctop * [0.5, 0.5, 0.3],
        ctop * [1, 1, 0.7],
        ctop,
        5,
    )
    add_tubes(b, canes, 0.007, 8)
    n = count(geo.integers(9, 14), density)
    cane = geo.integers(0, nc, n)
    at = canes[cane, geo.integers(2, 5, n)]
    az = golden_azimuths(geo, n, 0.3)
    pel = geo.uniform(0.75, 1.25, n)
    plen = geo.uniform(0.06, 0.1, n)
    pdir = direction(az, pel)
    pend = at + pdir * plen[:, None]
    add_tubes(
        b,
        bezier(at, at + pdir * plen[:, None] * 0.4, pend - direction(az, pel - 0.3) * plen[:, None] * 0.3, pend, 6),
        np.linspace(0.0045, 0.0028, 6)[None].repeat(n, 0),
        6,
    )
    V, F, UV, _ = strip_cards(
        pend,
        az + geo.normal(0, 0.1, n),
        pel - geo.uniform(0.4, 0.8, n),
        geo.uniform(0.14, 0.2, n),
        pick(geo, leaf_t, n),
        size,
        segments=6,
        bend=geo.uniform(0.5, 1.0, n),
        bend_power=1.5,
        fold=0.18,
        twist=geo.normal(0, 0.25, n),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.45, 0.58, 0.38))


def grow_hydrangea(geo, tex, size, density) -> Grown:
    """Hydrangea (bigleaf, mophead): a shrub of woody canes with opposite serrated leaves and big
    round flower heads of four-petalled florets, some white, some purple (organ labels
    ``flower_white`` and ``flower_purple``, as the paper's hand-made label texture)."""
    atlas = Atlas(size)
    col = {
        "base": (0.2, 0.42, 0.14),
        "light": (0.32, 0.55, 0.2),
        "dark": (0.12, 0.28, 0.08),
        "vein": (0.35, 0.55, 0.25),
    }
    leaf_t = tiles(
        atlas,
        tex,
        4,
        0.42,
        0.62,
        lambda i: P.lamina(
            P.serrate(P.ovate(0.42, 0.75), 26, 0.06),
            col["base"],
            col["light"],
            col["dark"],
            col["vein"],
            LEAF,
            vein_spacing=0.09,
            vein_slope=0.7,
            midrib=0.008,
        ),
    )
    white = [
        {
            "base": (0.93, 0.94, 0.9),
            "light": (1.0, 1.0, 0.97),
            "dark": (0.82, 0.86, 0.78),
            "vein": (0.85, 0.9, 0.8),
            "centre": (0.78, 0.86, 0.62),
        },
        {
            "base": (0.9, 0.92, 0.88),
            "light": (0.98, 0.98, 0.96),
            "dark": (0.8, 0.84, 0.8),
            "vein": (0.84, 0.88, 0.82),
            "centre": (0.86, 0.9, 0.7),
        },
    ]
    purple = [
        {
            "base": (0.55, 0.36, 0.78),
            "light": (0.7, 0.52, 0.88),
            "dark": (0.4, 0.25, 0.62),
            "vein": (0.62, 0.45, 0.82),
            "centre": (0.42, 0.3, 0.7),
        },
        {
            "base": (0.66, 0.38, 0.75),
            "light": (0.8, 0.55, 0.86),
            "dark": (0.5, 0.26, 0.6),
            "vein": (0.7, 0.45, 0.8),
            "rim": (0.5, 0.3, 0.75),
        },
        {
            "base": (0.48, 0.42, 0.85),
            "light": (0.62, 0.58, 0.92),
            "dark": (0.36, 0.3, 0.7),
            "vein": (0.55, 0.5, 0.85),
            "centre": (0.7, 0.55, 0.85),
        },
    ]
    white_t = tiles(atlas, tex, 2, 0.1, 0.72, lambda i: P.ellipse_leaf(FLOWER_WHITE, white[i], 0.02))
    purple_t = tiles(atlas, tex, 3, 0.1, 0.72, lambda i: P.ellipse_leaf(FLOWER_PURPLE, purple[i], 0.02))
    b = MeshBuilder()
    nc = count(geo.integers(4, 7), min(density, 1.5))
    caz = golden_azimuths(geo, nc, 0.3)
    crad = geo.uniform(0.05, 0.13, nc)
    ctop = np.column_stack([crad * np.cos(caz), crad * np.sin(caz), geo.uniform(0.2, 0.3, nc)])
    p0 = np.column_stack([0.012 * np.cos(caz), 0.012 * np.sin(caz), np.full(nc, -0.005)])
    canes = bezier(p0, p0 + [0, 0, 0.08], ctop - (ctop - p0) * [0.4, 0.4, 0.2] - [0, 0, 0.03], ctop, 9)
    add_tubes(b, canes, np.linspace(0.005, 0.0032, 9)[None].repeat(nc, 0), 7, WOOD)
    # opposite leaf pairs at nodes along the canes, successive pairs crossed
    nodes = [3, 4, 5, 6, 7]
    lb, laz, lel = [], [], []
    for c in range(nc):
        for j, k in enumerate(nodes):
            if geo.random() > 0.85 * min(density, 1.0) + 0.1:
                continue
            tan = canes[c, k + 1] - canes[c, k - 1]
            ta = np.arctan2(tan[1], tan[0])
            a = ta + np.pi / 2 * (j % 2) + geo.normal(0, 0.2)
            for side in (0.0, np.pi):
                lb.append(canes[c, k])
                laz.append(a + side)
                lel.append(geo.uniform(0.0, 0.6))
    lb, laz, lel = np.array(lb), np.array(laz), np.array(lel)
    n = len(lb)
    pet_end = lb + direction(laz, lel + 0.3) * 0.015
    add_tubes(b, np.stack([lb, pet_end], axis=1), 0.0015, 5)
    V, F, UV, _ = strip_cards(
        pet_end,
        laz,
        lel,
        geo.uniform(0.08, 0.115, n),
        pick(geo, leaf_t, n),
        size,
        segments=4,
        bend=geo.uniform(0.3, 0.8, n),
        fold=0.2,
        twist=geo.normal(0, 0.3, n),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    # flower heads: florets on a spherical cap above each cane tip, four solid petals each
    purple_head = geo.random(nc) < 0.55
    purple_head[0], purple_head[-1] = False, True  # both colours occur
    for c in range(nc):
        tan = unit((canes[c, -1] - canes[c, -3])[None])[0]
        R = geo.uniform(0.045, 0.06)
        centre = canes[c, -1] + tan * R * 0.55
        m = count(90 * (R / 0.05) ** 2, density)
        i = np.arange(m) + 0.5
        cosang = 1 - (1 - np.cos(1.9)) * i / m  # Fibonacci points on a cap of 1.9 rad
        ang = i * 2.39996
        ref = np.array([1.0, 0, 0]) if abs(tan[2]) < 0.9 else np.array([0, 1.0, 0])
        e1 = unit(np.cross(tan, ref)[None])[0]
        e2 = np.cross(tan, e1)
        sinang = np.sqrt(1 - cosang**2)
        dirs = cosang[:, None] * tan + sinang[:, None] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
        dirs = unit(dirs + geo.normal(0, 0.08, (m, 3)))
        fc = centre + dirs * R * geo.uniform(0.92, 1.04, (m, 1))
        add_tubes(b, np.stack([centre + dirs * R * 0.4, fc], axis=1), 0.0008, 3)
        petals = 4
        fn = dirs.repeat(petals, 0)
        spin = np.repeat(geo.uniform(0, 2 * np.pi, m), petals) + np.tile(np.arange(petals) * np.pi / 2, m)
        plen = np.repeat(geo.uniform(0.011, 0.016, m), petals)
        choices = purple_t if purple_head[c] else white_t
        # a few florets of the other colour, as real heads shade from one to the other
        mixed = geo.random(m) < 0.12
        rects = pick(geo, choices, m * petals)
        other = pick(geo, white_t if purple_head[c] else purple_t, m * petals)
        rects = np.where(np.repeat(mixed, petals)[:, None], other, rects)
        V, F, UV = solid_leaves(fc.repeat(petals, 0), fn, spin, plen, plen * 0.72, rects, size, ring=6, fold=-0.12)
        b.add(V, F, UV, CARDS, 0)
    return Grown(
        b,
        atlas,
        labels_for("leaf", "stem", "flower_white", "flower_purple"),
        (0.3, 0.42, 0.18),
        wood_colour=(0.42, 0.33, 0.22),
    )


def grow_boxwood(geo, tex, size, density) -> Grown:
    """Boxwood (Buxus sempervirens), clipped into a ball: tens of thousands of small, solid,
    glossy leaves as real polygons on a short trunk; opacity cuts (almost) nothing."""
    atlas = Atlas(size)
    cols = [
        {"base": (0.16, 0.34, 0.1), "light": (0.26, 0.46, 0.14), "dark": (0.09, 0.22, 0.06), "vein": (0.4, 0.55, 0.25)},
        {"base": (0.24, 0.44, 0.12), "light": (0.38, 0.58, 0.2), "dark": (0.14, 0.3, 0.08), "vein": (0.5, 0.65, 0.3)},
        {"base": (0.34, 0.5, 0.16), "light": (0.5, 0.64, 0.24), "dark": (0.22, 0.38, 0.1), "vein": (0.6, 0.7, 0.35)},
    ]
    leaf_t = tiles(atlas, tex, 9, 0.12, 0.6, lambda i: P.ellipse_leaf(LEAF, cols[i % 3], 0.05))
    sprig_t = tiles(
        atlas, tex, 3, 0.3, 0.5, lambda i: P.sprig(LEAF, STEM, cols[i % 3], (0.42, 0.34, 0.2), pairs=4 + i % 2)
    )
    b = MeshBuilder()
    centre = np.array([0.0, 0.0, 0.175])
    radii = np.array([0.14, 0.14, 0.125]) * geo.uniform(0.95, 1.05, 3)
    # trunk and branches (mostly hidden inside)
    nt = int(geo.integers(2, 4))
    taz = geo.uniform(0, 2 * np.pi, nt)
    tb = np.column_stack([0.008 * np.cos(taz), 0.008 * np.sin(taz), np.full(nt, -0.008)])
    tt = centre + np.column_stack([0.02 * np.cos(taz), 0.02 * np.sin(taz), np.full(nt, -0.04)])
    add_tubes(b, bezier(tb, tb + [0, 0, 0.05], tt - [0, 0, 0.04], tt, 6), 0.006, 8, WOOD)
    nb = 40
    bd = unit(geo.normal(0, 1, (nb, 3)) + [0, 0, 0.3])
    bs = tt[geo.integers(0, nt, nb)]
    be = centre + bd * radii * 0.8
    add_tubes(
        b,
        bezier(bs, bs + (be - bs) * 0.3 + [0, 0, 0.02], be - bd * 0.03, be, 5),
        np.linspace(0.004, 0.0015, 5)[None].repeat(nb, 0),
        5,
        WOOD,
    )
    # leaves in the outer shell of the ball
    n = count(7500, density)
    d = unit(geo.normal(0, 1, (n, 3)))
    depth = 1.0 - 0.16 * geo.random(n) ** 1.5
    pos = centre + d * radii * depth[:, None]
    pos[:, 2] = np.maximum(pos[:, 2], 0.045 + 0.02 * geo.random(n))
    normal = unit(d / radii * radii.mean() + geo.normal(0, 0.45, (n, 3)))
    length = geo.uniform(0.012, 0.02, n)
    V, F, UV = solid_leaves(
        pos, normal, geo.uniform(0, 2 * np.pi, n), length, length * 0.6, pick(geo, leaf_t, n), size, ring=8, fold=0.12
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    # a few alpha-card sprigs filling gaps, as real boxwood assets have: the little opacity
    # this plant relies on (the paper measured 0.15 % more pixels with opacity ignored)
    ns = count(24, density)
    d = unit(geo.normal(0, 1, (ns, 3)) + [0, 0, 0.2])
    pos = centre + d * radii * geo.uniform(0.8, 0.9, (ns, 1))
    saz, sel = azel(unit(d + geo.normal(0, 0.4, (ns, 3))))
    V, F, UV, _ = strip_cards(
        pos,
        saz,
        sel,
        geo.uniform(0.03, 0.045, ns),
        pick(geo, sprig_t, ns),
        size,
        segments=2,
        bend=0.3,
        fold=0.1,
        roll=geo.uniform(0, np.pi, ns),
    )
    b.add(V, F, UV, CARDS, b.instances(ns))
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.4, 0.32, 0.2), wood_colour=(0.4, 0.32, 0.2))


def grow_coltsfoot(geo, tex, size, density) -> Grown:
    """Coltsfoot (Tussilago farfara): heart-shaped, coarsely toothed leaves on long petioles
    from the ground, and dandelion-like yellow flower heads on scaly stalks."""
    atlas = Atlas(size)
    col = {"base": (0.3, 0.5, 0.2), "light": (0.45, 0.62, 0.3), "dark": (0.18, 0.34, 0.1), "vein": (0.6, 0.7, 0.45)}
    leaf_t = tiles(atlas, tex, 5, 0.32, 1.0, lambda i: P.cordate(LEAF, col))
    fcol = {
        "base": (0.98, 0.82, 0.08),
        "light": (1.0, 0.9, 0.3),
        "dark": (0.92, 0.7, 0.05),
        "inner": (0.95, 0.7, 0.08),
        "disc": (0.95, 0.62, 0.08),
    }
    flower_t = tiles(atlas, tex, 2, 0.16, 1.0, lambda i: P.radial_flower(FLOWER, fcol, 34, centre=0.3, rays=True))
    anchor = P.cordate_anchor()
    b = MeshBuilder()
    n = count(geo.integers(6, 10), density)
    az = golden_azimuths(geo, n, 0.3)
    rad = geo.uniform(0.03, 0.11, n)
    h = geo.uniform(0.06, 0.15, n)
    attach = np.column_stack([rad * np.cos(az), rad * np.sin(az), h])
    p0 = np.column_stack([0.006 * np.cos(az), 0.006 * np.sin(az), np.full(n, -0.005)])
    add_tubes(
        b,
        bezier(
            p0,
            p0 + [0, 0, 0.05],
            attach - np.column_stack([0.01 * np.cos(az), 0.01 * np.sin(az), np.full(n, 0.03)]),
            attach,
            7,
        ),
        0.002,
        6,
    )
    tilt = geo.uniform(0.25, 0.7, n)  # leaf blade tilted down and outward
    normal = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    # spin so that the card's tip (+s) points away from the plant's axis
    outward = np.column_stack([np.cos(az), np.sin(az), np.zeros(n)])
    V, F, UV = plate_cards(
        attach,
        normal,
        np.zeros(n),
        geo.uniform(0.08, 0.13, n),
        pick(geo, leaf_t, n),
        size,
        cup=-0.05,
        anchor=anchor,
        corner=0.82,
    )
    # rotate each leaf about its normal so that its e2 axis follows "outward"
    V = _spin_towards(V, attach, normal, outward, anchor_dir=_plate_e2(normal))
    b.add(V, F, UV, CARDS, b.instances(n))
    nf = int(geo.integers(2, 5))
    faz = geo.uniform(0, 2 * np.pi, nf)
    frad = geo.uniform(0.02, 0.08, nf)
    fpos = np.column_stack([frad * np.cos(faz), frad * np.sin(faz), geo.uniform(0.1, 0.17, nf)])
    q0 = np.column_stack([0.005 * np.cos(faz), 0.005 * np.sin(faz), np.full(nf, -0.005)])
    add_tubes(b, bezier(q0, q0 + [0, 0, 0.06], fpos - [0, 0, 0.04], fpos, 7), 0.0022, 6)
    fn = unit(np.column_stack([0.4 * np.cos(faz), 0.4 * np.sin(faz), np.ones(nf)]))
    add_cards(
        b,
        plate_cards(
            fpos, fn, geo.uniform(0, 6.3, nf), geo.uniform(0.03, 0.04, nf), pick(geo, flower_t, nf), size, cup=0.1
        ),
        instance=False,
    )
    return Grown(b, atlas, labels_for("leaf", "stem", "flower"), (0.45, 0.32, 0.22))


def _plate_e2(normal: np.ndarray) -> np.ndarray:
    from .shapes import frame

    return frame(normal, np.zeros(len(normal)))[1]


def _spin_towards(
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


def grow_basket_grass(geo, tex, size, density) -> Grown:
    """Basket grass (Lomandra-like): a dense clump of fine, arching, strap-like blades; each
    card carries a few blades, so most of every card is cut away."""
    atlas = Atlas(size)
    cols = [
        {"base": (0.3, 0.5, 0.16), "light": (0.45, 0.62, 0.24), "dark": (0.18, 0.34, 0.09), "tip": (0.62, 0.6, 0.35)},
        {"base": (0.26, 0.46, 0.14), "light": (0.4, 0.58, 0.22), "dark": (0.15, 0.3, 0.08), "tip": (0.55, 0.55, 0.3)},
    ]
    blade_t = tiles(atlas, tex, 5, 0.95, 0.2, lambda i: P.grass_blades(LEAF, cols[i % 2], 5 + i % 3, 0.02))
    b = MeshBuilder()
    n = count(geo.integers(100, 130), density)
    az = geo.uniform(0, 2 * np.pi, n)
    r0 = 0.025 * np.sqrt(geo.random(n))
    ba = geo.uniform(0, 2 * np.pi, n)
    base = np.column_stack([r0 * np.cos(ba), r0 * np.sin(ba), np.full(n, 0.002)])
    elev = geo.uniform(0.7, 1.5, n)
    V, F, UV, _C = strip_cards(
        base,
        az,
        elev,
        geo.uniform(0.2, 0.33, n),
        pick(geo, blade_t, n),
        size,
        segments=8,
        bend=geo.uniform(0.8, 2.2, n) * elev / 1.1,
        bend_power=1.5,
        twist=geo.normal(0, 0.6, n),
        curl=geo.normal(0, 0.3, n),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    # a few culms
    nc = count(6, density)
    caz = geo.uniform(0, 2 * np.pi, nc)
    tops = np.column_stack([0.06 * np.cos(caz), 0.06 * np.sin(caz), geo.uniform(0.14, 0.24, nc)])
    add_tubes(
        b,
        bezier(np.zeros((nc, 3)) - [0, 0, 0.004], tops * [0.1, 0.1, 0.4], tops * [0.6, 0.6, 0.85], tops, 6),
        0.0012,
        5,
    )
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.6, 0.55, 0.32))


def grow_common_fern(geo, tex, size, density) -> Grown:
    """Common (male) fern (Dryopteris filix-mas): a shuttlecock of upright, lanceolate, bipinnate
    fronds on short brown stipes."""
    atlas = Atlas(size)
    col = {
        "base": (0.24, 0.5, 0.14),
        "light": (0.4, 0.64, 0.22),
        "dark": (0.13, 0.32, 0.07),
        "vein": (0.45, 0.62, 0.25),
        "rachis": (0.38, 0.42, 0.18),
    }
    env = lambda Y: np.sin(np.pi * np.clip(Y, 0, 1) ** 0.75) ** 0.7
    frond_t = tiles(
        atlas,
        tex,
        3,
        0.94,
        0.34,
        lambda i: P.frond(
            LEAF,
            col,
            pinnae=20 + i,
            envelope=env,
            pinna_width=0.56,
            angle=0.25,
            stipe=0.14,
            lobes=7 + i % 2,
            rachis=0.008,
        ),
    )
    b = MeshBuilder()
    n = count(geo.integers(10, 16), density)
    az = golden_azimuths(geo, n, 0.25)
    r0 = geo.uniform(0.006, 0.02, n)
    base = np.column_stack([r0 * np.cos(az), r0 * np.sin(az), np.full(n, 0.01)])
    elev = geo.uniform(1.0, 1.35, n)
    V, F, UV, C = strip_cards(
        base,
        az,
        elev,
        geo.uniform(0.27, 0.36, n),
        pick(geo, frond_t, n),
        size,
        segments=8,
        bend=geo.uniform(0.5, 1.2, n),
        bend_power=1.6,
        fold=0.12,
        twist=geo.normal(0, 0.3, n),
        curl=geo.normal(0, 0.2, n),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    seg = 1.0 / 8
    stipe = np.linspace(0, 1, 4)
    path = C[:, 0][:, None] + (C[:, 1] - C[:, 0])[:, None] * (stipe * 0.14 / seg)[None, :, None]
    path[:, 0, 2] = -0.004
    add_tubes(b, path, np.linspace(0.0028, 0.002, 4)[None].repeat(n, 0), 6)
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.36, 0.28, 0.16))


#: species name -> (grower, default atlas size, one-line description)
SPECIES: dict[str, tuple[Callable[..., Grown], int, str]] = {
    "indian_cress": (
        grow_indian_cress,
        512,
        "Indian cress (nasturtium): round peltate leaves on long petioles, orange flowers",
    ),
    "boston_fern": (grow_boston_fern, 1024, "Boston fern: long arching once-pinnate fronds (alpha cards)"),
    "amaryllis": (grow_amaryllis, 1024, "Amaryllis: bulb, arching strap leaves, tall scape with red trumpet flowers"),
    "bog_marshcress": (grow_bog_marshcress, 512, "Bog marshcress: small rosette of lobed leaves, tiny yellow flowers"),
    "chinese_evergreen": (
        grow_chinese_evergreen,
        1024,
        "Chinese evergreen (Aglaonema): broad silver-patterned leaves on petioles",
    ),
    "hydrangea": (grow_hydrangea, 1024, "Hydrangea shrub with white and purple flower heads (organ labels)"),
    "boxwood": (grow_boxwood, 512, "Boxwood ball: ~60k triangles of small solid leaves, almost no opacity"),
    "coltsfoot": (grow_coltsfoot, 512, "Coltsfoot: heart-shaped toothed leaves on long petioles, yellow flower heads"),
    "basket_grass": (grow_basket_grass, 1024, "Basket grass: dense clump of fine arching blades (alpha cards)"),
    "common_fern": (
        grow_common_fern,
        1024,
        "Common (male) fern: upright bipinnate fronds in a shuttlecock (alpha cards)",
    ),
}
