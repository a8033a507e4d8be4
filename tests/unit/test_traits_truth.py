"""Trait truth against independent truth: a cut-out card of known size and tilt (analytic), a
species' leaf areas against its atlas rasterised a second way (point samples, supersampled), leaf
counts against the mesh's instances, and de Wit's classes against leaves drawn from them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import LEAF_LABELS as LEAF
from conftest import leaf_card as _card
from conftest import rotation_x as _rotation_x

from agrisim.errors import UserError
from agrisim.plugins.apps.traits.opaque_area import face_opaque_area, kept_texels
from agrisim.plugins.apps.traits.truth import DE_WIT, INCLINATION_BINS, de_wit_shares, nearest_de_wit, plant_traits
from agrisim.plugins.formats.plant_asset import load_plant
from agrisim.plugins.plants.procedural import grow
from agrisim.plugins.sinks.dataset.glb import export_glb
from agrisim.scene.model import Mesh, Plant

NUDGE = 1e-3 * np.sqrt(2)


def _ellipse(h: int, w: int, a: float, b: float) -> np.ndarray:
    """Alpha of an ellipse with half-axes ``a`` (along x, of the texture's width) and ``b``
    (of its height) as shares of the texture's half size."""
    y, x = np.mgrid[0:h, 0:w]
    u, v = (x + 0.5) / w * 2 - 1, (y + 0.5) / h * 2 - 1
    return np.where((u / a) ** 2 + (v / b) ** 2 <= 1.0, 255, 0).astype(np.uint8)


@pytest.mark.parametrize("tilt", [0.0, 33.0, 75.0])
def test_a_half_cut_card_read_from_gltf_counts_half_its_area_at_its_tilt(tmp_path: Path, tilt: float) -> None:
    """A user's glTF card, 10 cm square, its texture's left half cut away (alpha 0), written with
    its leaf instance and read back as a user's plant: half the card's area; its
    inclination is its tilt, its azimuth where the tilt leans its upward normal (-y: 270)."""
    alpha = np.zeros((16, 16), np.uint8)
    alpha[:, 8:] = 255
    path = tmp_path / "card.glb"
    export_glb(_card(0.1, alpha, tilt), path, LEAF)
    plant = load_plant(path, place=False)
    traits = plant_traits(plant)
    assert traits.leaf_count == 1
    leaf = traits.leaves[0]
    # exactly half, up to glTF's float32 vertices
    assert leaf.area_m2 == pytest.approx(0.005, rel=1e-6)
    assert traits.leaf_area_m2 == pytest.approx(0.005, rel=1e-6)
    assert leaf.inclination_deg == pytest.approx(tilt, abs=1e-4)
    if tilt > 0:
        assert leaf.azimuth_deg == pytest.approx(270.0, abs=1e-4)
    shares = np.zeros(len(INCLINATION_BINS) - 1)
    shares[min(int(tilt // 10), len(shares) - 1)] = 1.0
    np.testing.assert_allclose(leaf.inclination_shares, shares)


def test_an_elliptic_leaf_has_its_axes_as_length_and_width() -> None:
    """A card whose opaque texels form an ellipse of axes 8 x 3 cm on a 10 cm card (tilted: the
    lengths are along the surface): midrib length 8 cm and width 3 cm, within two texels
    (10 cm / 256); area pi a b within the texels' staircase."""
    alpha = _ellipse(256, 256, 0.8, 0.3)
    traits = plant_traits(Plant("ellipse", _card(0.1, alpha, 40.0), LEAF))
    leaf = traits.leaves[0]
    texel = 0.1 / 256
    assert leaf.length_m == pytest.approx(0.08, abs=2 * texel)
    assert leaf.width_m == pytest.approx(0.03, abs=2 * texel)
    assert leaf.area_m2 == pytest.approx(np.pi * 0.04 * 0.015, rel=0.01)
    assert leaf.area_m2 == pytest.approx((alpha > 0).sum() * texel**2, rel=1e-9)  # the texels, exactly


def test_a_solid_card_has_its_sides_as_length_and_width() -> None:
    """An uncut card of 8 x 3 cm, two triangles, tilted: length and width are its sides (its
    corners bound it, however coarse its triangles), its area their product."""
    card = _card(1.0, np.full((4, 4), 255, np.uint8))
    local = np.array([[-0.04, -0.015, 0], [0.04, -0.015, 0], [0.04, 0.015, 0], [-0.04, 0.015, 0]])
    card.vertices = local @ _rotation_x(20.0).T + [0.05, 0.0, 0.1]
    leaf = plant_traits(Plant("card", card, LEAF)).leaves[0]
    assert leaf.length_m == pytest.approx(0.08, rel=1e-6)
    assert leaf.width_m == pytest.approx(0.03, rel=1e-6)
    assert leaf.area_m2 == pytest.approx(0.08 * 0.03, rel=1e-9)


def _rasterised_area(mesh: Mesh, faces: np.ndarray, supersample: int = 8) -> float:
    """The opaque area of ``faces``, the second way: each triangle rasterised on a grid
    ``supersample`` times finer than the atlas (a subpixel counts when its centre is inside),
    each drawn subpixel's texel looked up."""
    total = 0.0
    areas = mesh.areas
    for f in faces:
        keep = kept_texels(mesh.materials[mesh.face_material[f]])
        if isinstance(keep, bool):
            total += areas[f] if keep else 0.0
            continue
        h, w = keep.shape
        uv = mesh.uvs[mesh.faces[f]].astype(np.float64) * [w * supersample, h * supersample]
        e1, e2 = uv[1] - uv[0], uv[2] - uv[0]
        det = e1[0] * e2[1] - e1[1] * e2[0]
        if abs(det) < 2e-3:  # no area to draw: its first corner's texel, the module's rule
            c = np.floor(uv[0] / supersample).astype(int)
            total += areas[f] * keep[c[1] % h, c[0] % w]
            continue
        lo, hi = np.floor(uv.min(axis=0)).astype(int), np.ceil(uv.max(axis=0)).astype(int)
        ys, xs = np.mgrid[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]
        # (centres nudged off the half-integers, where the diagonals of texel-aligned cards pass
        # and two triangles would both claim a subpixel)
        px, py = xs.ravel() + 0.5 + NUDGE - uv[0, 0], ys.ravel() + 0.5 + NUDGE / 3 - uv[0, 1]
        s_, t_ = (e2[1] * px - e2[0] * py) / det, (-e1[1] * px + e1[0] * py) / det
        inside = (s_ >= 0) & (t_ >= 0) & (s_ + t_ <= 1)
        rows = (ys.ravel()[inside] // supersample) % h
        cols = (xs.ravel()[inside] // supersample) % w
        total += areas[f] * keep[rows, cols].sum() / (0.5 * abs(det))
    return total


def test_a_species_leaf_areas_agree_with_its_atlas_rasterised_a_second_way() -> None:
    """Coltsfoot's leaves (cut-out cards, curved): each leaf's exact opaque area against the
    same texels counted by rasterising every triangle on a grid 8x finer than the atlas, within
    the rasteriser's sampling error (measured at most 1e-5 of a leaf's area; 2e-4 allowed)."""
    plant = grow("coltsfoot", 0)
    mesh = plant.mesh
    traits = plant_traits(plant)
    exact = face_opaque_area(mesh)
    assert mesh.face_instance is not None
    for leaf in traits.leaves:
        faces = np.flatnonzero(mesh.face_instance == leaf.id)
        assert leaf.area_m2 == pytest.approx(exact[faces].sum(), rel=1e-9)
        assert leaf.area_m2 == pytest.approx(_rasterised_area(mesh, faces), rel=2e-4)
    assert traits.leaf_area_m2 < 0.9 * mesh.areas[mesh.face_instance > 0].sum()  # the cut-outs are off


def test_leaf_count_is_the_instances_of_the_truth() -> None:
    """Every leaf instance of the mesh with opaque texels is one leaf, by its id."""
    plant = grow("bog_marshcress", 0)
    mesh = plant.mesh
    assert mesh.face_instance is not None
    opaque = face_opaque_area(mesh) > 0
    ids = set(np.unique(mesh.face_instance[opaque & (mesh.face_instance > 0)]).tolist())
    traits = plant_traits(plant)
    assert {leaf.id for leaf in traits.leaves} == ids
    assert traits.leaf_count == len(ids) > 1


@pytest.mark.parametrize("kind", DE_WIT)
def test_leaves_drawn_from_a_de_wit_class_are_fitted_to_it(kind: str) -> None:
    """300 small square leaves, their inclinations drawn from ``kind``'s density (inverse of its
    cumulative share), azimuths uniform: the plant's leaf angle distribution is nearest ``kind``."""
    rng = np.random.default_rng(1)
    grid = np.linspace(0, np.pi / 2, 2001)
    cumulative = np.concatenate([[0], np.cumsum(np.interp(grid[1:], grid, np.gradient(_cdf(kind, grid), grid)))])
    cumulative /= cumulative[-1]
    tilts = np.degrees(np.interp(rng.uniform(size=300), cumulative, grid))
    meshes = []
    for i, tilt in enumerate(tilts):
        spin = rng.uniform(0, 2 * np.pi)
        card = _card(0.01, np.full((2, 2), 255, np.uint8), float(tilt))
        c, s = np.cos(spin), np.sin(spin)
        v = (card.vertices - [0, 0, 0.1]) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [0, 0, 0.1 + i * 1e-3]
        meshes.append((v, card))
    vertices = np.concatenate([v for v, _ in meshes])
    faces = np.concatenate([card.faces + 4 * i for i, (_, card) in enumerate(meshes)])
    uvs = np.concatenate([card.uvs for _, card in meshes])
    mesh = Mesh(
        "leaves",
        vertices,
        faces,
        meshes[0][1].materials,
        np.zeros(len(faces), np.int32),
        uvs,
        np.repeat(np.arange(1, len(meshes) + 1), 2).astype(np.uint16),
    )
    traits = plant_traits(Plant("drawn", mesh, LEAF))
    assert traits.de_wit_class == kind, traits.de_wit_distance


def _cdf(kind: str, theta: np.ndarray) -> np.ndarray:
    shares = de_wit_shares(kind)  # (only to be sure the module's classes are the ones drawn here)
    assert np.isclose(shares.sum(), 1.0)
    from agrisim.plugins.apps.traits.truth import _cumulative

    return _cumulative(kind, theta)


def test_the_nearest_class_of_its_own_shares_is_itself() -> None:
    for kind in DE_WIT:
        assert nearest_de_wit(de_wit_shares(kind))[0] == kind


def test_a_plant_without_leaves_is_refused() -> None:
    card = _card(0.1, np.full((4, 4), 255, np.uint8))
    bare = Mesh("stick", card.vertices, card.faces, card.materials, card.face_material, card.uvs)
    with pytest.raises(UserError, match="no leaves"):
        plant_traits(Plant("stick", bare, LEAF))


def test_leaves_are_clustered_apart_where_a_gap_parts_them_and_together_where_they_touch() -> None:
    """Instance-free counting (DBSCAN on the leaves' points, ids dropped): two 4 cm sheets of
    points on the 1 mm grid, 2 cm apart, are two clusters each one leaf; the same sheets meeting
    at a fold (an L) are one cluster that mixes them; a few stray points count as nothing."""
    from agrisim.plugins.apps.traits.estimate import cluster_leaves

    u, v = np.meshgrid(np.arange(40) * 1e-3, np.arange(40) * 1e-3)
    flat = np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])
    apart = cluster_leaves({1: flat, 2: flat + [0.06, 0.0, 0.0]})
    assert (apart.count, apart.one_leaf, apart.merged) == (2, 2, 0)
    upright = np.column_stack([np.full(u.size, 0.04), v.ravel(), u.ravel() + 1e-3])
    stray = np.array([[0.3, 0.3, 0.3], [-0.3, 0.2, 0.1], [0.2, -0.3, 0.0]])
    folded = cluster_leaves({1: flat, 2: np.concatenate([upright, stray])})
    assert (folded.count, folded.one_leaf, folded.merged) == (1, 0, 1)
