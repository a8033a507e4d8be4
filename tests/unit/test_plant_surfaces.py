"""The procedural plants' surfaces: normal maps from the veins' relief (checked against the
slopes of known height fields, and the veins' grooves on a painted leaf), roughness maps, leaf
optics from PROSPECT-D (against the spectra's physics) and ageing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agrisim.plugins.plants.procedural import grow, optics, painters
from agrisim.plugins.plants.procedural.growing import Ageing, tiles
from agrisim.plugins.plants.procedural.species import LOOKS, SPECIES
from agrisim.plugins.plants.procedural.textures import Atlas, normal_texels
from agrisim.scene import colour


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


# ------------------------------------------------------------------------ leaf optics


def test_a_flat_spectrum_is_grey_and_a_red_one_red():
    """The spectrum-to-colour step: 0.5 at every wavelength is grey 0.5 (D65 is sRGB's white);
    light only above 600 nm is red."""
    wavelengths = np.arange(400, 2501)
    np.testing.assert_allclose(optics.spectrum_rgb(wavelengths, np.full(len(wavelengths), 0.5)), 0.5, atol=0.003)
    r, g, b = optics.spectrum_rgb(wavelengths, (wavelengths > 600).astype(float))
    assert r > 3 * g and b < 0.01


def test_prospect_leaves_are_green_and_follow_their_pigments_and_thickness():
    """PROSPECT-D's leaves: green (green reflected most), darker green with more chlorophyll,
    less translucent when thicker (more mesophyll layers), and yellowing (red up against
    green) when chlorophyll is lost."""
    leaf = optics.Leaf()
    (r, g, b), (tr, tg, tb) = optics.leaf_rgb(leaf)
    assert g > r > b and tg > tr and 0.02 < g < 0.3
    assert optics.leaf_rgb(optics.Leaf(cab=70))[0][1] < g
    assert optics.translucency(optics.Leaf(n=2.5))[1] < optics.translucency(leaf)[1]
    yellowed, _ = optics.leaf_rgb(leaf.aged(green=0.2))
    assert yellowed[0] / yellowed[1] > 1.5 * r / g


def test_species_translucency_is_their_own_leaf_optics():
    """Each species' cards transmit as PROSPECT-D says its leaf does: boxwood's thick leaves
    least, the thin fern pinnae most."""
    look = {name: grow(name, 0).mesh.materials[0].transmittance for name in ("boxwood", "boston_fern", "hydrangea")}
    for name, t in look.items():
        assert t == optics.translucency(LOOKS[name].leaf)
    assert look["boxwood"][1] < look["hydrangea"][1] < look["boston_fern"][1]


def test_veins_are_rougher_than_the_blade():
    atlas = Atlas(256)
    colours = dict(base=(0.3, 0.5, 0.2), light=(0.4, 0.6, 0.3), dark=(0.2, 0.3, 0.1), vein=(0.6, 0.7, 0.4))
    tile = atlas.paint(
        atlas.tile(0.9, 0.45),
        painters.lamina(painters.ovate(), *colours.values(), 1, midrib=0.01),
        np.random.default_rng(0),
    )
    texture, factor = atlas.metallic_roughness(0.4)
    rough = texture[tile.r0 : tile.r0 + tile.h, tile.c0 : tile.c0 + tile.w, 1] / 255.0 * factor
    row, middle = tile.h // 2, tile.w // 2
    assert rough[row, middle] > 0.5 and abs(rough[row, middle + tile.w // 5] - 0.4) < 0.04
    assert texture[..., 2].max() == 0  # not metallic


def test_aged_leaves_yellow_and_brown_as_their_optics_say():
    """An aged variant of a leaf keeps its outline and labels and turns, where it is dead (a
    dried tip), to the colour given per unit of luminance (PROSPECT-D's dead leaf) at the
    healthy texel's own luminance, in linear light; near the base it stays as it was."""
    colours = dict(base=(0.3, 0.5, 0.2), light=(0.3, 0.5, 0.2), dark=(0.3, 0.5, 0.2), vein=(0.3, 0.5, 0.2))
    leaf = painters.lamina(painters.strap(), *colours.values(), 1, vein_strength=0.0)
    brown = np.array([0.9, 0.7, 0.3])
    old = painters.aged(leaf, 0.0, 0, 0.3, np.ones(3), brown)
    healthy_atlas, aged_atlas = Atlas(256), Atlas(256)
    t1 = healthy_atlas.paint(healthy_atlas.tile(0.9, 0.3), leaf, np.random.default_rng(0))
    t2 = aged_atlas.paint(aged_atlas.tile(0.9, 0.3), old, np.random.default_rng(0))
    a = healthy_atlas.rgba[t1.r0 : t1.r0 + t1.h, t1.c0 : t1.c0 + t1.w]
    b = aged_atlas.rgba[t2.r0 : t2.r0 + t2.h, t2.c0 : t2.c0 + t2.w]
    assert np.array_equal(a[..., 3], b[..., 3])
    tip = (slice(2, 6), slice(t1.w // 2 - 2, t1.w // 2 + 2))  # near the tip, on the midrib: dead
    healthy = colour.srgb_to_linear(a[tip][..., :3].reshape(-1, 3) / 255.0)
    dead = colour.srgb_to_linear(b[tip][..., :3].reshape(-1, 3) / 255.0)
    luminance = healthy @ np.array([0.2126, 0.7152, 0.0722])
    np.testing.assert_allclose(dead, luminance[:, None] * brown, rtol=0.05, atol=0.002)
    base = (slice(t1.h - 40, t1.h - 30), slice(t1.w // 2 - 2, t1.w // 2 + 2))
    assert np.abs(b[base].astype(int) - a[base].astype(int)).max() <= 1  # alive near the base


def six_variants(painter, look) -> list[np.ndarray]:  # noqa: ANN001
    """Six variants of the leaf ``painter`` paints, as ``look`` varies them: RGBA tiles (float)."""
    atlas = Atlas(512)
    made = tiles(atlas, np.random.default_rng(0), 6, 0.3, 0.5, lambda i: painter, look)
    return [atlas.rgba[t.r0 : t.r0 + t.h, t.c0 : t.c0 + t.w].astype(float) for t in made]


@pytest.mark.parametrize("name", [n for n in SPECIES if LOOKS[n].ageing.share > 0])
def test_the_last_leaf_variants_of_species_that_age_are_aged(name):
    """Of six leaf variants in a species' look, the last ``share`` are aged (redder: yellowing
    and browning raise red against green), the others as without ageing, texel for texel."""
    colours = dict(base=(0.3, 0.5, 0.2), light=(0.35, 0.55, 0.25), dark=(0.25, 0.45, 0.15), vein=(0.5, 0.6, 0.3))

    leaf = painters.lamina(painters.ovate(), *colours.values(), 1)
    aged, plain = six_variants(leaf, LOOKS[name]), six_variants(leaf, dataclasses.replace(LOOKS[name], ageing=Ageing()))
    n_aged = round(LOOKS[name].ageing.share * 6)
    assert n_aged >= 1
    for a, p in zip(aged[: 6 - n_aged], plain[: 6 - n_aged], strict=True):
        assert np.array_equal(a, p)
    leaf = plain[-1][..., 3] >= 128
    redness = lambda t: t[..., 0][leaf].mean() / t[..., 1][leaf].mean()  # noqa: E731
    assert redness(aged[-1]) > 1.01 * redness(plain[-1])


def test_leaf_variants_differ_in_shade():
    """Each leaf variant of a look has its own shade: variants of one flat grey-green leaf
    differ in brightness and in the balance of red (yellow-green) against blue (blue-green)."""

    def flat(X, Y, px, rng):  # noqa: ANN001, ANN202
        return np.ones(X.shape), np.broadcast_to([0.4, 0.5, 0.3], X.shape + (3,)), np.ones(X.shape, np.uint8)

    variants = six_variants(flat, dataclasses.replace(LOOKS["boxwood"], ageing=Ageing()))
    means = np.array([v[..., :3].reshape(-1, 3).mean(0) for v in variants])
    assert means[:, 1].std() > 3.0  # 8-bit levels
    assert (means[:, 0] / means[:, 2]).std() > 0.02


@pytest.mark.parametrize("name", list(SPECIES))
def test_every_leaf_holds_its_own_chlorophyll(name):
    """Each leaf (each leaf instance) is one colour, its own, and that colour is PROSPECT-D's
    reflectance of the species' leaf with 1 to 1 + ``chlorophyll`` times the palest leaf's
    chlorophyll, against the palest; stems and flowers are untinted."""
    mesh, look = grow(name, 2).mesh, LOOKS[name]
    leaf_faces = mesh.face_instance > 0
    per_face = mesh.colors[mesh.faces]  # (faces, corners, rgb)
    assert (per_face[~leaf_faces] == 1.0).all()
    leaf_of = mesh.face_instance[leaf_faces]
    corners = per_face[leaf_faces]
    assert (corners == corners[:, :1]).all()  # one colour over each face ...
    first = {}
    for leaf, c in zip(leaf_of.tolist(), corners[:, 0].tolist(), strict=True):
        assert first.setdefault(leaf, c) == c  # ... and over each leaf
    tints = np.array(list(first.values()))
    # leaves alike only by chance (boxwood's 7500 draws meet a float32 twice or so)
    assert len(np.unique(tints, axis=0)) >= 0.99 * len(tints)
    ks = np.linspace(1.0, 1.0 + look.chlorophyll, 241)
    r0 = np.asarray(optics.leaf_rgb(look.leaf)[0])
    curve = np.array([optics.leaf_rgb(dataclasses.replace(look.leaf, cab=look.leaf.cab * k))[0] for k in ks[::8]])
    curve = np.clip(curve / r0, 0.0, 1.0)
    # every tint on PROSPECT's curve (within the piecewise-linear table's error)
    nearest = np.abs(tints[:, None, :] - curve[None]).max(axis=-1).min(axis=1)
    assert nearest.max() < 0.02, nearest.max()
    assert tints[:, 0].max() - tints[:, 0].min() > 0.05  # and spread along it


def test_the_average_leaf_keeps_the_painted_colour(monkeypatch):
    """The atlas paints the palest leaf (the painted colour over the mean tint), so that over
    many leaves (boxwood's ~7500) the colour is what the painters gave."""
    from agrisim.plugins.plants import procedural

    look = LOOKS["boxwood"]
    plant = grow("boxwood", 0)
    tints = plant.mesh.colors[plant.mesh.faces[plant.mesh.face_instance > 0][:, 0]]
    np.testing.assert_allclose(tints.mean(axis=0), look.mean_tint(), atol=0.01)
    monkeypatch.setattr(procedural, "_palest", lambda atlas, look: None)
    painted = grow("boxwood", 0).mesh.materials[0]
    cards = plant.mesh.materials[0]
    leaf = painted.labels == 1
    ours = colour.srgb_to_linear(cards.albedo[leaf][:, :3] / 255.0) * look.mean_tint()
    theirs = colour.srgb_to_linear(painted.albedo[leaf][:, :3] / 255.0)
    np.testing.assert_allclose(ours, theirs, atol=0.006)  # 8-bit sRGB steps
