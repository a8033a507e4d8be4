"""Herbs with broad leaves: Indian cress, amaryllis, bog marshcress, Chinese evergreen, coltsfoot."""

from __future__ import annotations

import numpy as np

from agrisim.plugins.mesh_builder import MeshBuilder

from . import painters as P
from .growing import (
    CARDS,
    FLOWER,
    LEAF,
    WOOD,
    Grown,
    add_cards,
    add_tubes,
    azel,
    count,
    curvature,
    golden_azimuths,
    labels_for,
    pick,
    plate_e2,
    roll_towards,
    spin_towards,
    tiles,
)
from .shapes import bezier, direction, plate_cards, strip_cards, unit
from .textures import Atlas


# A species' recipe, organ by organ, reads top to bottom as the plant is built.
def grow_indian_cress(geo, tex, size, density, look=None) -> Grown:
    """Nasturtium (Tropaeolum majus): ~0.2 m, round peltate leaves on long petioles from a few
    sprawling stems, orange five-petalled flowers."""
    atlas = Atlas(size)
    col = {"base": (0.33, 0.52, 0.22), "light": (0.5, 0.66, 0.33), "dark": (0.2, 0.36, 0.13), "vein": (0.72, 0.8, 0.55)}
    leaf_t = tiles(atlas, tex, 6, 0.3, 1.0, lambda i: P.peltate(LEAF, col), look=look)
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
            centre,
            normal,
            geo.uniform(0, 2 * np.pi, nl),
            diam,
            pick(geo, leaf_t, nl),
            size,
            corner=0.8,
            waves=8,
            **curvature(geo, nl, cup=(-0.12, -0.03), wave=(0.01, 0.05), droop=(0.0, 0.08)),
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


# A species' recipe, organ by organ, reads top to bottom as the plant is built.
def grow_amaryllis(geo, tex, size, density, look=None) -> Grown:
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
        look=look,
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
        waves=3,
        **curvature(geo, n, cup=(-0.2, 0.0), wave=(0.0, 0.06)),  # keeled, channelled
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


def grow_bog_marshcress(geo, tex, size, density, look=None) -> Grown:
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
    leaf_t = tiles(atlas, tex, 5, 0.48, 0.5, lambda i: P.lobed(LEAF, col, lobes=3.5 + 0.5 * (i % 3)), look=look)
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
        waves=4,
        **curvature(geo, n, cup=(0.05, 0.25), wave=(0.05, 0.15)),
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


def grow_chinese_evergreen(geo, tex, size, density, look=None) -> Grown:
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
        look=look,
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
        waves=3,
        **curvature(geo, n, cup=(0.05, 0.2), wave=(0.05, 0.15)),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.45, 0.58, 0.38))


def grow_coltsfoot(geo, tex, size, density, look=None) -> Grown:
    """Coltsfoot (Tussilago farfara): heart-shaped, coarsely toothed leaves on long petioles
    from the ground, and dandelion-like yellow flower heads on scaly stalks."""
    atlas = Atlas(size)
    col = {"base": (0.3, 0.5, 0.2), "light": (0.45, 0.62, 0.3), "dark": (0.18, 0.34, 0.1), "vein": (0.6, 0.7, 0.45)}
    leaf_t = tiles(atlas, tex, 5, 0.32, 1.0, lambda i: P.cordate(LEAF, col), look=look)
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
        anchor=anchor,
        corner=0.7,
        waves=9,
        **curvature(geo, n, cup=(-0.1, 0.02), wave=(0.02, 0.06), droop=(0.05, 0.25)),
    )
    # rotate each leaf about its normal so that its e2 axis follows "outward"
    V = spin_towards(V, attach, normal, outward, anchor_dir=plate_e2(normal))
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
