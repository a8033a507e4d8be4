"""The procedural plants' surfaces: normal maps from the veins' relief (checked against the
slopes of known height fields, and the veins' grooves on a painted leaf)."""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.plugins.plants.procedural import grow, painters
from agrisim.plugins.plants.procedural.species import SPECIES
from agrisim.plugins.plants.procedural.textures import Atlas, normal_texels


def decode(texels: np.ndarray) -> np.ndarray:
    """Unit normals of glTF normal-map texels."""
    n = texels.astype(float) / 255.0 * 2.0 - 1.0
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def test_normal_texels_are_the_slopes_of_the_height():
    """h = a sin(k x) + b y on a grid whose rows run from the tip (y = 1) down: the normal is
    (-a k cos(k x), -b, 1), normalised (x along the columns, y toward the tip)."""
    px = 1.0 / 200
    y, x = np.mgrid[200:-1:-1, 0:101] * px  # rows from y = 1 down to 0
    a, k, b = 0.01, 40.0, 0.3
    n = decode(normal_texels(a * np.sin(k * x) + b * y, px))
    want = np.stack([-a * k * np.cos(k * x), np.full_like(x, -b), np.ones_like(x)], axis=-1)
    want /= np.linalg.norm(want, axis=-1, keepdims=True)
    inner = (slice(1, -1), slice(1, -1))  # (np.gradient is one-sided on the border)
    np.testing.assert_allclose(n[inner], want[inner], atol=0.012)  # 8 bits a component, and the difference quotient


def test_a_leafs_veins_lie_in_grooves_of_its_upper_side():
    """A simple leaf's midrib is a groove: beside it the normals lean in toward it; far from
    any vein the surface faces out of the card."""
    atlas = Atlas(512)
    colours = dict(base=(0.3, 0.5, 0.2), light=(0.4, 0.6, 0.3), dark=(0.2, 0.3, 0.1), vein=(0.6, 0.7, 0.4))
    leaf = painters.lamina(painters.ovate(), *colours.values(), 1, midrib=0.01, vein_spacing=0.2)
    tile = atlas.paint(atlas.tile(0.9, 0.45), leaf, np.random.default_rng(0))
    n = decode(atlas.normals[tile.r0 : tile.r0 + tile.h, tile.c0 : tile.c0 + tile.w])
    middle, row = tile.w // 2, tile.h // 2
    half_rib = 0.01 * (1.2 - 0.7 * 0.5) * (tile.h - 1)  # the groove's half-width at mid-length, texels
    side = int(round(0.5 * half_rib))
    assert n[row, middle - side, 0] > 0.2 and n[row, middle + side, 0] < -0.2  # leaning in
    floor = (tile.w - 1) // 2, tile.w // 2  # (one column, or the two either side of the middle)
    assert abs(n[row, floor[0], 0] + n[row, floor[1], 0]) < 0.05  # the groove's floor: level
    between = n[row, middle + int(3 * half_rib) : middle + int(6 * half_rib)]
    assert between[:, 2].min() > 0.97  # beyond the midrib, before the next vein: facing out


@pytest.mark.parametrize("name", list(SPECIES))
def test_every_species_cards_carry_the_relief_of_their_veins(name):
    plant = grow(name, 0)
    cards = next(m for m in plant.mesh.materials if m.albedo is not None)
    assert cards.normal_map is not None and cards.normal_map.shape == cards.albedo.shape[:2] + (3,)
    opaque = cards.albedo[..., 3] >= 128
    tilt = np.degrees(np.arccos(np.clip(decode(cards.normal_map[opaque])[:, 2], -1, 1)))
    share = float(np.mean(tilt > 2.0))
    assert 0.05 < share < 0.9, share  # veins, grooves and creases, not an even roughness
