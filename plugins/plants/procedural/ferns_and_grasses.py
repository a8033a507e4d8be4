"""Fronds and blades, almost all alpha-tested cards: Boston fern, basket grass, common fern."""

from __future__ import annotations

import numpy as np

from agrisim.plugins.mesh_builder import MeshBuilder

from . import painters as P
from .growing import (
    CARDS,
    LEAF,
    Grown,
    add_tubes,
    count,
    curvature,
    golden_azimuths,
    labels_for,
    pick,
    tiles,
)
from .shapes import bezier, strip_cards
from .textures import Atlas


def grow_boston_fern(geo, tex, size, density, look=None) -> Grown:
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

    def env(Y: np.ndarray) -> np.ndarray:
        return np.sin(np.pi * np.clip(Y, 0, 1) ** 0.5) ** 0.4

    frond_t = tiles(
        atlas,
        tex,
        5,
        0.94,
        aspect,
        lambda i: P.frond(LEAF, col, pinnae=34 + 2 * i, envelope=env, pinna_width=0.46, angle=0.3, stipe=0.07),
        look=look,
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
        **curvature(geo, n, cup=(0.1, 0.3)),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    stipe = np.linspace(0, 1, 4)
    seg = 1.0 / 10
    path = C[:, 0][:, None] + (C[:, 1] - C[:, 0])[:, None] * (stipe * 0.07 / seg)[None, :, None]
    path[:, 0, 2] = -0.004
    add_tubes(b, path, 0.0016, 5)
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.3, 0.35, 0.15))


def grow_basket_grass(geo, tex, size, density, look=None) -> Grown:
    """Basket grass (Lomandra-like): a dense clump of fine, arching, strap-like blades; each
    card carries a few blades, so most of every card is cut away."""
    atlas = Atlas(size)
    cols = [
        {"base": (0.3, 0.5, 0.16), "light": (0.45, 0.62, 0.24), "dark": (0.18, 0.34, 0.09), "tip": (0.62, 0.6, 0.35)},
        {"base": (0.26, 0.46, 0.14), "light": (0.4, 0.58, 0.22), "dark": (0.15, 0.3, 0.08), "tip": (0.55, 0.55, 0.3)},
    ]
    blade_t = tiles(atlas, tex, 5, 0.95, 0.2, lambda i: P.grass_blades(LEAF, cols[i % 2], 5 + i % 3, 0.02), look=look)
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
        **curvature(geo, n, cup=(-0.15, 0.0)),  # a channel: the margins up
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


def grow_common_fern(geo, tex, size, density, look=None) -> Grown:
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

    def env(Y: np.ndarray) -> np.ndarray:
        return np.sin(np.pi * np.clip(Y, 0, 1) ** 0.75) ** 0.7

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
        look=look,
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
        **curvature(geo, n, cup=(0.05, 0.2)),
    )
    b.add(V, F, UV, CARDS, b.instances(n))
    seg = 1.0 / 8
    stipe = np.linspace(0, 1, 4)
    path = C[:, 0][:, None] + (C[:, 1] - C[:, 0])[:, None] * (stipe * 0.14 / seg)[None, :, None]
    path[:, 0, 2] = -0.004
    add_tubes(b, path, np.linspace(0.0028, 0.002, 4)[None].repeat(n, 0), 6)
    return Grown(b, atlas, labels_for("leaf", "stem"), (0.36, 0.28, 0.16))
