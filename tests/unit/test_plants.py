"""The procedural plant library, checked against independent truth: the mesh contract of
:mod:`agrisim.scene.model`, the shared texture lookups of :mod:`agrisim.scene.texturing`, the size of the
cameras' safe cylinder, the paper's organ colours and its Table 2 ordering of how much each
asset relies on opacity."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from agrisim.plugins.plants.procedural import ProceduralPlantOptions, grow
from agrisim.plugins.plants.procedural.species import SPECIES
from agrisim.registry import Registry, make_plugin_manager
from agrisim.scene.model import Mesh, Plant
from agrisim.scene.texturing import cutaway_fraction, interpolate_uv, label_at, opaque_samples, sample_surface

NAMES = [
    "indian_cress",
    "boston_fern",
    "amaryllis",
    "bog_marshcress",
    "chinese_evergreen",
    "hydrangea",
    "boxwood",
    "coltsfoot",
    "basket_grass",
    "common_fern",
]
RADIUS, HEIGHT = 0.28, 0.40  # the cylinder every plant must fit in above the soil


@pytest.fixture(scope="module")
def plants() -> dict[str, Plant]:
    # How long each takes to build is measured by bench/plant_build.py, not asserted here.
    return {name: grow(name, 0) for name in NAMES}


@pytest.fixture(scope="module")
def cutaways(plants) -> dict[str, float]:
    return {name: cutaway_fraction(p.mesh, samples=60_000, seed=1) for name, p in plants.items()}


def surface_labels(mesh: Mesh, count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(opaque?, label id) of ``count`` area-uniform surface samples."""
    _, faces, bary = sample_surface(mesh, count, np.random.default_rng(seed))
    keep = opaque_samples(mesh, faces, bary)
    uv = interpolate_uv(mesh, faces, bary)
    labels = np.zeros(len(faces), np.uint8)
    mats = mesh.face_material[faces]
    for i in np.unique(mats):
        sel = mats == i
        labels[sel] = label_at(mesh.materials[i], uv[sel])
    return keep, labels


def card_faces(mesh: Mesh) -> np.ndarray:
    """Faces whose material cuts (alpha-tested cards and textured leaves)."""
    cuts = np.array([m.cuts for m in mesh.materials])
    return np.flatnonzero(cuts[mesh.face_material])


# ------------------------------------------------------------------------- the library


def test_all_ten_species_are_registered_through_the_entry_point(monkeypatch):
    for var in ("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "AGRISIM_LOAD_PLUGINS"):
        monkeypatch.delenv(var, raising=False)
    specs = Registry(make_plugin_manager()).specs("plant")
    assert set(NAMES) <= set(specs)
    for name in NAMES:
        spec = specs[name]
        assert spec.description and "\n" not in spec.description
        assert spec.options_model is ProceduralPlantOptions
        assert "agrisim" in spec.distribution
        plant = spec.factory(spec.options_model()).build(3)
        assert isinstance(plant, Plant) and plant.name == name


def test_options_are_documented_and_strict():
    for name, field in ProceduralPlantOptions.model_fields.items():
        assert field.description, f"option {name} has no docstring"
    with pytest.raises(ValidationError):
        ProceduralPlantOptions(colour="red")
    for bad in (0.1, 3.5):
        with pytest.raises(ValidationError):
            ProceduralPlantOptions(scale=bad)


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_plant_other_seed_other_plant(name, plants):
    a = plants[name].mesh
    b = grow(name, 0).mesh
    for attr in ("vertices", "faces", "uvs", "face_material", "face_instance"):
        np.testing.assert_array_equal(getattr(a, attr), getattr(b, attr), err_msg=attr)
    for ma, mb in zip(a.materials, b.materials, strict=True):
        for attr in ("albedo", "labels"):
            if getattr(ma, attr) is None:
                assert getattr(mb, attr) is None
            else:
                np.testing.assert_array_equal(getattr(ma, attr), getattr(mb, attr))
    c = grow(name, 1).mesh
    assert a.vertices.shape != c.vertices.shape or not np.allclose(a.vertices, c.vertices)


def test_the_plant_seed_grows_another_individual_and_the_same_seed_the_same_bytes(tmp_path, cli, monkeypatch):
    """``[plants.NAME] seed`` and ``--plant-seed``: another individual of the species (its own
    scene file), the same file byte for byte for the same seed, whatever the run's seed (each
    grown anew: the session's plant cache is off here)."""
    from agrisim.scene.plant_cache import PLANT_CACHE_ENV

    monkeypatch.delenv(PLANT_CACHE_ENV, raising=False)
    from agrisim.app.arguments import build_parser
    from agrisim.config import build_config
    from agrisim.plant_choice import resolve_plant
    from agrisim.plugins.apps.flags import overrides_from_args
    from agrisim.plugins.sinks.dataset.glb import export_glb

    registry = Registry(make_plugin_manager())

    def saved(*argv: str) -> bytes:
        config = build_config(overrides_from_args(build_parser().parse_args(["run", "--plant", "coltsfoot", *argv])))
        plant = resolve_plant(registry, config)
        path = tmp_path / f"{len(list(tmp_path.iterdir()))}.glb"
        export_glb(plant.mesh, path, plant.labels)
        return path.read_bytes()

    three = saved("--plant-seed", "3")
    assert saved("--set", "plants.coltsfoot.seed=3", "--seed", "7") == three
    assert saved() != three and saved("--seed", "3") == three  # (by default the run's seed)
    for bad in ("-1", "4294967296"):
        code, _, err = cli(["run", "--plant", "coltsfoot", "--plant-seed", bad, "--out", str(tmp_path / "out")])
        assert code == 2 and err.count("\n") == 1 and "--plant-seed" in err and "Traceback" not in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", NAMES)
def test_mesh_is_valid_textured_and_fits_the_camera_cylinder(name, plants):
    plant = plants[name]
    m = plant.mesh
    # the Mesh constructor's checks pass on a rebuilt copy too
    Mesh(m.name, m.vertices, m.faces, m.materials, m.face_material, m.uvs, m.face_instance)
    assert np.all(m.areas > 0)
    v = m.vertices
    assert np.hypot(v[:, 0], v[:, 1]).max() <= RADIUS
    assert v[:, 2].max() <= HEIGHT
    assert v[:, 2].min() >= -0.02  # stems may reach a little into the soil
    assert v[:, 2].max() > 0.08  # a plant, not a mat
    cards = card_faces(m)
    assert len(cards) > 0
    uv = m.uvs[m.faces[cards].ravel()]
    assert uv.min() >= 0.0 and uv.max() <= 1.0
    for mat in m.materials:
        if mat.cuts:
            assert mat.alpha_mode == "MASK" and mat.alpha_cutoff == 0.5 and mat.double_sided
            assert mat.albedo.shape[:2] == mat.labels.shape
            assert 256 <= mat.albedo.shape[0] <= 1024
            a = mat.albedo[..., 3]
            assert (a == 255).any() and (a == 0).any()  # alpha carries the shapes
        else:
            assert mat.alpha_mode == "OPAQUE"


@pytest.mark.parametrize("name", NAMES)
def test_card_uvs_stay_on_labelled_texels(name, plants):
    """Every card vertex and face centre maps to a labelled texel: no UV bleeds into empty
    atlas space, and with opacity ignored (repopa) the whole card is labelled."""
    m = plants[name].mesh
    cards = card_faces(m)
    tri = m.faces[cards]
    for mi in np.unique(m.face_material[cards]):
        mat = m.materials[mi]
        sel = m.face_material[cards] == mi
        corners = m.uvs[tri[sel]].reshape(-1, 2)
        centres = m.uvs[tri[sel]].mean(axis=1)
        assert np.all(label_at(mat, corners) > 0)
        assert np.all(label_at(mat, centres) > 0)


@pytest.mark.parametrize("name", NAMES)
def test_every_opaque_surface_sample_is_labelled(name, plants):
    plant = plants[name]
    keep, labels = surface_labels(plant.mesh, 40_000)
    assert keep.any()
    assert np.all(labels[keep] > 0)
    known = {lab.id for lab in plant.labels.labels}
    assert set(np.unique(labels)) <= known
    names = {lab.name for lab in plant.labels.labels}
    assert {"background", "leaf", "stem"} <= names
    assert plant.labels.by_name("background").id == 0
    assert plant.organs == (len(plant.labels.labels) > 2)
    # every organ the table names is really on the plant's visible surface
    for lab in plant.labels.labels[1:]:
        assert np.any(labels[keep] == lab.id), f"{name}: no opaque {lab.name}"


@pytest.mark.parametrize("name", NAMES)
def test_leaf_instances_number_the_cards(name, plants):
    m = plants[name].mesh
    inst = m.face_instance.astype(np.int64)
    ids = np.unique(inst[inst > 0])
    np.testing.assert_array_equal(ids, np.arange(1, len(ids) + 1))
    assert len(ids) >= 5
    # stems are not leaves
    stems = np.array([not mat.cuts for mat in m.materials])[m.face_material]
    assert np.all(inst[stems] == 0)
    # every leaf-labelled card face belongs to a leaf instance
    cards = card_faces(m)
    centres = m.uvs[m.faces[cards]].mean(axis=1)
    lab = np.zeros(len(cards), np.uint8)
    for mi in np.unique(m.face_material[cards]):
        sel = m.face_material[cards] == mi
        lab[sel] = label_at(m.materials[mi], centres[sel])
    leaf_id = plants[name].labels.by_name("leaf").id
    assert np.all(inst[cards[lab == leaf_id]] > 0)
    # an instance is one small organ, not scattered over the plant
    order = np.argsort(inst, kind="stable")
    starts = np.searchsorted(inst[order], ids)
    ends = np.searchsorted(inst[order], ids, side="right")
    for k in np.linspace(0, len(ids) - 1, min(len(ids), 25)).astype(int):
        verts = m.vertices[m.faces[order[starts[k] : ends[k]]].ravel()]
        assert np.ptp(verts, axis=0).max() < 0.4


# ---------------------------------------------------------------- opacity (paper Table 2)


def test_boxwood_is_dense_solid_geometry(plants, cutaways):
    m = plants["boxwood"].mesh
    assert len(m.faces) >= 50_000
    assert cutaways["boxwood"] < 0.05


@pytest.mark.parametrize("name", ["boston_fern", "common_fern", "basket_grass"])
def test_ferns_and_grass_are_mostly_alpha_cards(name, cutaways):
    assert cutaways[name] > 0.45


@pytest.mark.parametrize(
    "name", ["hydrangea", "indian_cress", "coltsfoot", "amaryllis", "chinese_evergreen", "bog_marshcress"]
)
def test_the_others_are_in_between(name, cutaways):
    assert 0.15 <= cutaways[name] <= 0.5


def test_cutaway_follows_the_papers_order_roughly(cutaways):
    """Table 2 (% more pixels with opacity ignored): boxwood 0.15 < hydrangea 3.2 < indian
    cress 6.4 < coltsfoot 7.7 < amaryllis 11.8 < chinese evergreen 14.3 < boston fern 33.5,
    bog marshcress 35.1 < common fern 42.4 < basket grass 67.4."""
    c = cutaways
    assert (
        c["boxwood"]
        < c["hydrangea"]
        < c["indian_cress"]
        < c["amaryllis"]
        < c["chinese_evergreen"]
        < c["bog_marshcress"]
    )
    assert c["hydrangea"] < c["coltsfoot"] < c["chinese_evergreen"]
    assert max(c["bog_marshcress"], c["chinese_evergreen"]) < min(c["boston_fern"], c["common_fern"], c["basket_grass"])
    assert c["basket_grass"] == max(c.values())


# ---------------------------------------------------------------------- hydrangea organs


def test_hydrangea_organs_have_the_papers_colours(plants):
    plant = plants["hydrangea"]
    assert plant.organs
    colours = {lab.name: lab.color for lab in plant.labels.labels}
    assert colours["leaf"] == (0, 255, 0)
    assert colours["flower_white"] == (0, 0, 255)
    assert colours["flower_purple"] == (255, 0, 0)
    r, g, b = colours["stem"]
    assert b > r > g and b >= 100  # deep purple
    ids = {lab.name: lab.id for lab in plant.labels.labels}
    assert len(set(ids.values())) == 5
    keep, labels = surface_labels(plant.mesh, 60_000, seed=3)
    for organ in ("leaf", "stem", "flower_white", "flower_purple"):
        assert np.count_nonzero(labels[keep] == ids[organ]) > 100, organ


def test_hydrangea_petal_labels_follow_petal_colour(plants):
    """The label texture marks white petals white and purple petals purple."""
    plant = plants["hydrangea"]
    mat = plant.mesh.materials[0]
    ids = {lab.name: lab.id for lab in plant.labels.labels}
    opaque = mat.albedo[..., 3] >= 128
    rgb = mat.albedo[..., :3].astype(int)
    white = opaque & (mat.labels == ids["flower_white"])
    purple = opaque & (mat.labels == ids["flower_purple"])
    assert white.any() and purple.any()
    assert rgb[white].mean(axis=0).min() > 180  # white-ish
    pm = rgb[purple].mean(axis=0)
    assert pm[2] > pm[1] + 40 and pm[0] > pm[1]  # purple: blue and red over green


# --------------------------------------------------------------------------------- scale


def test_scale_and_density_options():
    base = grow("coltsfoot", 4)
    big = grow("coltsfoot", 4, ProceduralPlantOptions(scale=2.0))
    np.testing.assert_allclose(big.mesh.vertices[:, :2], 2 * base.mesh.vertices[:, :2])
    sparse = grow("basket_grass", 4, ProceduralPlantOptions(density=0.5))
    dense = grow("basket_grass", 4)
    assert sparse.mesh.face_instance.max() < dense.mesh.face_instance.max()
    small_tex = grow("common_fern", 4, ProceduralPlantOptions(texture_size=256))
    assert small_tex.mesh.materials[0].albedo.shape[:2] == (256, 256)
    assert set(SPECIES) == set(NAMES)


def test_every_plant_source_uses_the_one_palette(plants):
    """Procedural species, Helios crops and files read without colours all take their label
    colours from agrisim.scene.palette, which holds the paper's four; within a plant no two
    labels share a colour."""
    from agrisim.plugins.plants.helios.convert import ORGANS
    from agrisim.scene.palette import PALETTE, PAPER

    assert PAPER == {
        "leaf": (0, 255, 0),
        "flower_white": (0, 0, 255),
        "flower_purple": (255, 0, 0),
        "stem": (96, 0, 128),
    }
    tables = [plant.labels.labels for plant in plants.values()] + [list(ORGANS)]
    for labels in tables:
        named = [lab for lab in labels if lab.id != 0]
        for lab in named:
            assert lab.color == PALETTE[lab.name], (lab.name, lab.color)
        assert len({lab.color for lab in named}) == len(named), named
