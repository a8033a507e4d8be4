"""The label colours: one palette, the paper's, used by every plant source.

The paper (Sec. 4, Fig. 3) paints its hydrangea's label texture with leaves green, white
flowers blue, purple flowers red and stems deep purple; a one-label plant is green. Organs the
paper does not name get colours in the same spirit: a flower of unknown colour is blue (as
white flowers), fruit red, and the stalks between stem and leaf or flower purple shades.
"""

from __future__ import annotations

BACKGROUND: tuple[int, int, int] = (0, 0, 0)

#: The paper's four organ colours, as its GIMP label textures use them (colour -> organ when a
#: user's label texture is read by colour).
PAPER: dict[str, tuple[int, int, int]] = {
    "leaf": (0, 255, 0),
    "flower_white": (0, 0, 255),
    "flower_purple": (255, 0, 0),
    "stem": (96, 0, 128),
}

#: Every organ name agrisim's plant sources use, with its colour.
PALETTE: dict[str, tuple[int, int, int]] = {
    **PAPER,
    "plant": PAPER["leaf"],
    "flower": PAPER["flower_white"],
    "fruit": PAPER["flower_purple"],
    "petiole": (200, 0, 255),
    "peduncle": (255, 0, 170),
}
