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
from .growing import Grown
from .herbs import grow_amaryllis, grow_bog_marshcress, grow_chinese_evergreen, grow_coltsfoot, grow_indian_cress
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
