"""Shrubs: the hydrangea with its white and purple flower heads, and the boxwood ball."""

from __future__ import annotations

import numpy as np

from agrisim.plugins.mesh_builder import MeshBuilder

from . import painters as P
from .growing import (
    CARDS,
    FLOWER_PURPLE,
    FLOWER_WHITE,
    LEAF,
    STEM,
    WOOD,
    Grown,
    add_tubes,
    azel,
    count,
    curvature,
    golden_azimuths,
    labels_for,
    pick,
    tiles,
)
from .shapes import bezier, direction, solid_leaves, strip_cards, unit
from .textures import Atlas


# A species' recipe, organ by organ, reads top to bottom as the plant is built.
def grow_hydrangea(geo, tex, size, density, look=None) -> Grown:
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
        look=look,
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
        waves=6,
        **curvature(geo, n, cup=(0.1, 0.25), wave=(0.0, 0.05)),
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


def grow_boxwood(geo, tex, size, density, look=None) -> Grown:
    """Boxwood (Buxus sempervirens), clipped into a ball: tens of thousands of small, solid,
    glossy leaves as real polygons on a short trunk; opacity cuts (almost) nothing."""
    atlas = Atlas(size)
    cols = [
        {"base": (0.16, 0.34, 0.1), "light": (0.26, 0.46, 0.14), "dark": (0.09, 0.22, 0.06), "vein": (0.4, 0.55, 0.25)},
        {"base": (0.24, 0.44, 0.12), "light": (0.38, 0.58, 0.2), "dark": (0.14, 0.3, 0.08), "vein": (0.5, 0.65, 0.3)},
        {"base": (0.34, 0.5, 0.16), "light": (0.5, 0.64, 0.24), "dark": (0.22, 0.38, 0.1), "vein": (0.6, 0.7, 0.35)},
    ]
    leaf_t = tiles(atlas, tex, 9, 0.12, 0.6, lambda i: P.ellipse_leaf(LEAF, cols[i % 3], 0.05), look=look)
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
