"""The ten procedural species standing in for the paper's Megascans plants (Table 1).

Each ``grow_<species>(geo, tex, size, density)`` (in :mod:`.herbs`, :mod:`.shrubs`,
:mod:`.ferns_and_grasses`, grown with :mod:`.growing`) returns a :class:`Grown`: the mesh parts (one
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

from .ferns_and_grasses import grow_basket_grass, grow_boston_fern, grow_common_fern
from .growing import Ageing, Grown, Look
from .herbs import grow_amaryllis, grow_bog_marshcress, grow_chinese_evergreen, grow_coltsfoot, grow_indian_cress
from .optics import Leaf
from .shrubs import grow_boxwood, grow_hydrangea

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

#: species name -> its leaves' look: PROSPECT-D's leaf (structure N, chlorophyll, carotenoids,
#: anthocyanins in µg/cm², water in cm, dry matter in g/cm², from the ranges of the LOPEX and
#: ANGERS leaf sets: thin fern pinnae, thick leathery boxwood), the upper side's roughness
#: (waxy and glossy: evergreen, boxwood, amaryllis; matte: coltsfoot's hairs), the lower side's
#: (matte) and its colour against the upper side's (paler; coltsfoot's is white-felted), and
#: how the species ages.
LOOKS: dict[str, Look] = {
    "indian_cress": Look(
        Leaf(n=1.4, cab=35, car=8, cw=0.015, cm=0.003), 0.55, 0.8, (1.25, 1.2, 1.3), Ageing(0.17, 0.8, 2)
    ),
    "boston_fern": Look(
        Leaf(n=1.3, cab=40, car=9, cw=0.008, cm=0.0035), 0.45, 0.75, (1.15, 1.1, 1.1), Ageing(0.2, 0.5, 0, 0.12)
    ),
    "amaryllis": Look(
        Leaf(n=1.9, cab=45, car=9, cw=0.03, cm=0.006), 0.3, 0.6, (1.2, 1.15, 1.2), Ageing(0.25, 0.3, 0, 0.2)
    ),
    "bog_marshcress": Look(
        Leaf(n=1.5, cab=38, car=8, ant=1.0, cw=0.012, cm=0.004), 0.45, 0.8, (1.2, 1.2, 1.25), Ageing(0.2, 0.7, 3)
    ),
    "chinese_evergreen": Look(
        Leaf(n=1.8, cab=30, car=7, cw=0.02, cm=0.005), 0.3, 0.6, (1.3, 1.25, 1.3), Ageing(0.15, 0.6, 0, 0.08)
    ),
    "hydrangea": Look(
        Leaf(n=1.6, cab=45, car=9, ant=0.5, cw=0.014, cm=0.005), 0.4, 0.8, (1.25, 1.2, 1.3), Ageing(0.2, 0.6, 4)
    ),
    "boxwood": Look(Leaf(n=2.2, cab=55, car=11, cw=0.012, cm=0.009), 0.25, 0.6, (1.3, 1.25, 1.2), Ageing(0.1, 0.6)),
    "coltsfoot": Look(Leaf(n=1.6, cab=40, car=8, cw=0.016, cm=0.005), 0.55, 0.95, (2.2, 1.8, 2.2), Ageing(0.2, 0.4, 5)),
    "basket_grass": Look(
        Leaf(n=1.6, cab=45, car=9, cw=0.01, cm=0.007), 0.4, 0.6, (1.1, 1.1, 1.1), Ageing(0.4, 0.3, 0, 0.25)
    ),
    "common_fern": Look(
        Leaf(n=1.4, cab=42, car=9, cw=0.009, cm=0.004), 0.45, 0.75, (1.2, 1.15, 1.15), Ageing(0.33, 0.5, 0, 0.1)
    ),
}
