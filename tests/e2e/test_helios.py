"""The ``helios`` plants: crop models grown by PyHelios, converted into agrisim's plant asset.

Checked against Helios itself where it can say: its organ queries and leaf objects (labels and
instances), its per-primitive solid fraction (our opacity coverage), its seeded generator
(determinism). Tiny episodes show the five crops of the issue going through the whole routine.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import isolated_env

from agrisim.app.arguments import build_parser
from agrisim.config import RenderConfig, RunConfig, build_config
from agrisim.episode import Episode
from agrisim.errors import UserError
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.apps.flags import overrides_from_args
from agrisim.plugins.plants import helios as H
from agrisim.plugins.plants.helios import convert as hc
from agrisim.registry import Registry, make_plugin_manager
from agrisim.scene.model import PLANT_FIT_HEIGHT as FIT_HEIGHT
from agrisim.scene.model import PLANT_FIT_RADIUS as FIT_RADIUS
from agrisim.scene.texturing import interpolate_uv, opaque

# No skip without PyHelios: CI installs the extra (scripts/setup.sh), and without it these tests
# fail with the one-line error that names it (pip install 'agrisim[helios]').

CROPS = ["tomato", "bean", "strawberry", "maize", "butterlettuce"]
LEAF, STEM, PETIOLE = hc.ORGAN_IDS["leaf"], hc.ORGAN_IDS["stem"], hc.ORGAN_IDS["petiole"]


@pytest.fixture(autouse=True)
def _plugins(monkeypatch: pytest.MonkeyPatch) -> None:
    for var in ("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "AGRISIM_LOAD_PLUGINS"):
        monkeypatch.delenv(var, raising=False)


def assert_one_line_error(code: int, err: str, *expected: str) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, f"not one line: {err!r}"
    for text in expected:
        assert text in err, f"{text!r} not in {err!r}"


# ------------------------------------------------------------------------------ the library


def test_every_helios_model_is_a_species():
    specs = Registry(make_plugin_manager()).specs("plant")
    models = H.available_models()
    assert set(CROPS) <= set(models)
    assert {f"helios:{m}" for m in models} == {n for n in specs if n.startswith("helios:")}
    spec = specs["helios:tomato"]
    assert spec.options_model is H.HeliosPlantOptions and "agrisim" in spec.distribution
    for name, field in H.HeliosPlantOptions.model_fields.items():
        assert field.description, f"option {name} has no docstring"


def test_same_seed_same_plant_and_seeds_differ():
    a, b, c = (H.grow("tomato", seed) for seed in (7, 7, 8))
    for field in ("vertices", "faces", "uvs", "face_material", "face_instance"):
        assert np.array_equal(getattr(a.mesh, field), getattr(b.mesh, field)), field
    assert [m.name for m in a.mesh.materials] == [m.name for m in b.mesh.materials]
    assert a.mesh.vertices.shape != c.mesh.vertices.shape or not np.array_equal(a.mesh.vertices, c.mesh.vertices)


def test_organs_and_leaf_instances_follow_helios():
    """Labels come from Helios's organ queries; each instance is exactly the blade of one Helios
    leaf object (its stalk is petiole), every leaf triangle belongs to one."""
    with H.helios_plant("strawberry", 60, 3) as (ctx, pa, plant_id):
        prims = hc.fetch(ctx, ctx.getAllUUIDs())
        labels, instances = hc.organ_labels(pa, ctx, plant_id, prims)
        row = {int(u): i for i, u in enumerate(prims.uuids)}
        queries = {
            "flower": pa.getAllFlowerUUIDs,
            "fruit": pa.getAllFruitUUIDs,
            "peduncle": pa.getAllPeduncleUUIDs,
            "stem": pa.getAllInternodeUUIDs,
        }
        for organ, query in queries.items():
            rows = [row[u] for u in query()]
            assert rows and np.all(labels[rows] == hc.ORGAN_IDS[organ]), organ
        objects = sorted(pa.getPlantLeafObjectIDs(plant_id))
        for k, obj in enumerate(objects, start=1):
            rows = np.array([row[u] for u in ctx.getObjectPrimitiveUUIDs(obj)])
            blade = rows[labels[rows] == LEAF]
            assert len(blade) and np.all(instances[blade] == k)
            assert np.all(instances[rows[labels[rows] != LEAF]] == 0)
        mesh = hc.to_mesh(ctx, prims, labels, instances, "helios:strawberry")
    assert set(np.unique(instances)) == set(range(len(objects) + 1))
    assert np.all(instances[labels == LEAF] > 0)
    organs = {lab.name for lab in hc.label_table(labels).labels}
    assert organs == {"background", "leaf", "stem", "petiole", "peduncle", "flower", "fruit"}
    # every triangle's material carries its organ label; leaves are alpha-tested cards
    face_label = np.array([m.label for m in mesh.materials])[mesh.face_material]
    assert np.array_equal(face_label, labels)
    assert all(m.alpha_mode == "MASK" and m.double_sided for m in mesh.materials if m.label == LEAF)

    # a compound leaf: tomato leaflets carry their stalks, which become petiole
    with H.helios_plant("tomato", 20, 0) as (ctx, pa, plant_id):
        prims = hc.fetch(ctx, ctx.getAllUUIDs())
        labels, instances = hc.organ_labels(pa, ctx, plant_id, prims)
        leaf_object_prims = set(ctx.getObjectPrimitiveUUIDs(pa.getPlantLeafObjectIDs(plant_id)))
    in_leaf_objects = np.isin(prims.uuids, list(leaf_object_prims))
    assert np.any(in_leaf_objects & (labels == PETIOLE)) and np.all(labels[in_leaf_objects] != STEM)
    textured = np.array([bool(t) for t in prims.textures])
    assert np.array_equal(labels == LEAF, in_leaf_objects & textured)


def tri_grid(n: int) -> np.ndarray:
    """n*n area-uniform barycentric points (B, C weights): cell centres of the unit square
    folded into the triangle. Deterministic, so coverage is a quadrature, not a noisy estimate."""
    g = (np.arange(n) + 0.5) / n
    a, b = (x.ravel() for x in np.meshgrid(g, g))
    fold = a + b > 1
    a[fold], b[fold] = 1 - a[fold], 1 - b[fold]
    return np.column_stack([a, b])


@pytest.mark.parametrize(
    "model,age", [("tomato", 20), ("bean", 20), ("strawberry", 60), ("maize", 10), ("butterlettuce", 40)]
)
def test_leaf_opacity_matches_helios_solid_fraction(model, age):
    """Independent truth: agrisim's opacity coverage of a leaf triangle (points in the triangle,
    UVs interpolated, ``texturing.opaque``) against Helios's ``getPrimitiveSolidFraction``.

    Helios rasterises the texture with texel i's centre at (i + 0.5) / (W - 1) rather than
    (i + 0.5) / W (up to a texel off) and caches fractions by UVs rounded to whole texels, so a
    triangle spanning few texels carries Helios's own error: per triangle the 0.02 tolerance holds
    where triangles span 64 texels or more each way (tomato, bean: ~1000-texel leaves; measured
    max 0.016). For every crop, the sampled leaf area's solid fraction agrees within 0.02
    (measured within 0.008; strawberry's 352 x 300 and maize's 1163 x 101 textures are small).
    """
    bary = tri_grid(150)
    with H.helios_plant(model, age, 11) as (ctx, pa, plant_id):
        prims = hc.fetch(ctx, ctx.getAllUUIDs())
        labels, instances = hc.organ_labels(pa, ctx, plant_id, prims)
        mesh = hc.to_mesh(ctx, prims, labels, instances, model)
        assert len(mesh.faces) == len(prims)  # all triangles: face k is primitive k
        textured_leaf = np.flatnonzero((labels == LEAF) & np.array([bool(t) for t in prims.textures]))
        sample = np.random.default_rng(0).choice(textured_leaf, min(150, len(textured_leaf)), replace=False)
        helios = np.asarray(ctx.getPrimitiveSolidFraction([int(prims.uuids[f]) for f in sample]), float)
    material = [mesh.materials[mesh.face_material[f]] for f in sample]
    ours = np.array(
        [
            opaque(m, interpolate_uv(mesh, np.full(len(bary), f), bary)).mean()
            for m, f in zip(material, sample, strict=True)
        ]
    )
    assert np.any(helios < 0.99) and np.any(ours < 0.99), "the sample holds no leaf edges"
    area = mesh.areas[sample]
    assert abs(np.sum(area * ours) - np.sum(area * helios)) / area.sum() <= 0.02
    # each triangle's UV extent in texels, along its narrower image axis
    spans = np.array(
        [np.ptp(mesh.uvs[mesh.faces[f]], axis=0) * m.albedo.shape[1::-1] for m, f in zip(material, sample, strict=True)]
    )
    spans = spans.min(axis=1)
    wide = spans >= 64
    if model in ("tomato", "bean"):
        assert wide.all()
    if wide.any():
        assert np.max(np.abs(ours - helios)[wide]) <= 0.02


def test_patches_palette_textures_and_colours():
    """A Helios context built by hand: a textured patch (two triangles, v flipped) with a palette
    PNG whose transparency is a tRNS entry, and a coloured triangle."""
    from pyhelios.types import RGBcolor, vec2, vec3

    ph = H._pyhelios()
    texture = str(next(Path(sys.modules["pyhelios"].__file__).parent.rglob("TomatoLeaf_blade.png")))
    rgba, has_alpha = hc.load_texture(texture)
    assert has_alpha and rgba.dtype == np.uint8 and rgba.shape[2] == 4 and 0 < (rgba[..., 3] >= 250).mean() < 1
    with ph.Context() as ctx:
        patch = ctx.addPatchTextured(vec3(0, 0, 0.1), vec2(0.2, 0.1), texture)
        tri = ctx.addTriangle(vec3(0, 0, 0), vec3(0.1, 0, 0), vec3(0, 0, 0.1), RGBcolor(0.5, 0.25, 0.0))
        prims = hc.fetch(ctx, [patch, tri])
        labels = np.array([LEAF, STEM], np.uint8)
        mesh = hc.to_mesh(ctx, prims, labels, np.array([1, 0], np.uint16), "helios:test")
        helios_sf = float(ctx.getPrimitiveSolidFraction(patch))
    assert len(mesh.faces) == 3 and np.array_equal(mesh.face_instance, [1, 1, 0])
    leaf = mesh.materials[mesh.face_material[0]]
    assert leaf.alpha_mode == "MASK" and leaf.alpha_cutoff == hc.HELIOS_ALPHA_CUTOFF
    assert np.array_equal(leaf.albedo, rgba)
    assert mesh.materials[mesh.face_material[2]].albedo is None and mesh.materials[mesh.face_material[2]].label == STEM
    # Helios's patch UVs (0,0) (1,0) (1,1) (0,1) run v upwards: glTF's v is flipped
    np.testing.assert_allclose(mesh.uvs[:4, 1], 1.0 - np.array([0.0, 0.0, 1.0, 1.0]), atol=1e-6)
    bary = tri_grid(300)
    cover = np.mean([opaque(leaf, interpolate_uv(mesh, np.full(len(bary), f), bary)).mean() for f in (0, 1)])
    assert abs(cover - helios_sf) <= 0.02


def test_plants_fit_the_routine_or_are_refused():
    plant = H.grow("tomato", 0, H.HeliosPlantOptions(age=40))
    v = plant.mesh.vertices
    assert np.hypot(v[:, 0], v[:, 1]).max() <= FIT_RADIUS + 1e-9 and v[:, 2].max() <= FIT_HEIGHT + 1e-9
    assert any("scaled by" in note for note in plant.notes)
    with pytest.raises(UserError, match=r"0\.85 m high.*--plant-age"):
        H.grow("tomato", 0, H.HeliosPlantOptions(age=40, fit="refuse"))
    small = H.grow("bean", 0)  # the default age fits at real size
    assert not any("scaled" in note for note in small.notes)


# ------------------------------------------------------------------------------ flags and errors


def test_plant_age_flag_and_settings(tmp_path, cli):
    args = build_parser().parse_args(["run", "--plant", "helios:tomato", "--plant-age", "25"])
    assert build_config(overrides_from_args(args)).plants == {"helios:tomato": {"age": 25.0}}  # the species' option
    for extra in (["--set", "plant_age=25"], ["--set", "plants.helios:tomato.age=25"]):
        config = build_config(
            overrides_from_args(build_parser().parse_args(["run", "--plant", "helios:tomato", *extra]))
        )
        plant = resolve_plant(Registry(make_plugin_manager()), config)
        assert "at 25 days" in plant.notes[0]
    out = tmp_path / "out"
    for bad in ("0", "-3", "nan", "inf", "1e9"):
        code, _, err = cli(["run", "--plant", "helios:tomato", "--plant-age", bad, "--out", str(out)])
        assert_one_line_error(code, err, "helios:tomato", "age")
    code, _, err = cli(["run", "--plant", "indian_cress", "--plant-age", "20", "--out", str(out)])
    assert_one_line_error(code, err, "--plant-age", "indian_cress")
    refuse = ["--set", "plants.helios:tomato.fit=refuse"]
    code, _, err = cli(["run", "--plant", "helios:tomato", "--plant-age", "40", *refuse, "--out", str(out)])
    assert_one_line_error(code, err, "helios:tomato at 40 days", "--plant-age")
    code, _, err = cli(["run", "--plant", "helios:nosuchcrop", "--out", str(out)])
    assert_one_line_error(code, err, "nosuchcrop", "tomato")
    assert not out.exists()


def test_without_pyhelios_helios_plants_name_the_extra(tmp_path, monkeypatch, cli):
    monkeypatch.setattr(H, "helios_available", lambda: False)
    H.available_models.cache_clear()
    try:
        assert not [n for n in Registry(make_plugin_manager()).specs("plant") if n.startswith("helios:")]
        code, out, _ = cli(["plugins"])
        assert code == 0 and "helios:" not in out and "indian_cress" in out
        code, _, err = cli(["run", "--plant", "helios:tomato", "--out", str(tmp_path / "out")])
        assert_one_line_error(code, err, "helios:tomato", "agrisim[helios]")
    finally:
        monkeypatch.undo()
        H.available_models.cache_clear()
    # for real: PyHelios cannot be imported at all, the plugin module still imports
    script = (
        "import sys; sys.modules['pyhelios'] = None\n"
        "from agrisim.app.cli import main\n"
        f"sys.exit(main(['run', '--plant', 'helios:bean', '--out', {str(tmp_path / 'out2')!r}]))\n"
    )
    env = isolated_env()
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert_one_line_error(proc.returncode, proc.stderr, "helios:bean", "agrisim[helios]")
    assert not (tmp_path / "out2").exists()


# ------------------------------------------------------------------------------ whole episodes


def tiny_run(plant: str, out: Path, frames, **output: object) -> tuple[Episode, object, object]:  # noqa: ANN001
    settings = {
        "plant": plant,
        "render": {"labels": "organs"},
        "renderer": {"raycast": {"shadow_samples": 0}},
        "physics": {"backend": "kinematic"},
        "routine": {"setpoints": "1x3"},  # no OMPL search for any seed tried: not about motion
        "camera": {"resolution": "320x180"},
        "output": {"out": str(out), "no_rrd": True, **output},
    }
    if "recon" in RunConfig.model_fields:  # the reconstruction is not what these tests check
        settings["recon"] = {"backend": "none"}
    episode = Episode(build_config(settings))
    episode.pm.register(frames)
    run, summary = episode.run()
    assert summary.reached == len(frames.images) == 6
    return episode, frames, run


@pytest.mark.parametrize("model", CROPS)
def test_crop_runs_the_routine_with_organs_and_instances(model, tmp_path, frames):
    rrd = tmp_path / "rec.rrd" if model == "tomato" else None
    recording = {"no_rrd": False, "rrd": str(rrd)} if rrd else {}
    episode, frames, run = tiny_run(f"helios:{model}", tmp_path / "run", frames, **recording)
    table = {lab.name: lab.id for lab in run.labels.labels}
    mesh_ids = set(np.unique(episode.plant.mesh.face_instance).tolist())
    seen: set[int] = set()
    for name, images in frames.images.items():
        labels, instances = images.labels, images.instances
        seen |= set(np.unique(labels).tolist())
        assert instances.dtype == np.uint16
        leaf = labels == table["leaf"]
        assert np.array_equal(instances > 0, leaf), name  # instances exactly on the leaf pixels
        assert set(np.unique(instances).tolist()) <= mesh_ids
        assert len(np.unique(instances)) > 2, f"{name}: a single leaf in view"
    expected = {"leaf", "stem"} | ({"flower", "fruit"} if model == "strawberry" else set())
    assert {table[n] for n in expected} <= seen, f"labels seen: {seen}, table: {table}"
    assert (run.out_dir / "instances" / f"{next(iter(frames.images))}.png").exists()
    assert (run.out_dir / "scene" / "plant.glb").exists()
    if rrd is not None:
        from rerun.chunk import RrdReader

        entities = {chunk.entity_path.lstrip("/") for chunk in RrdReader(rrd).stream()}
        assert {f"world/{arm}/camera/instances" for arm in ("r1", "r2")} <= entities
    # As in the paper's Table 2: ignoring opacity (RepOpa) labels more of the crop than its
    # texture's cut-outs do, from the routine's own views
    plant_pixels = {}
    for mode in ("texture", "repopa"):
        spec = episode.registry.get("renderer", "raycast")
        r = spec.factory(
            episode.scene,
            episode.cell,
            RenderConfig(hide_robots=True, seg_mode=mode),
            spec.options_model(shadow_samples=0),
        )
        views = [sp.world_T_camera for sps in episode.setpoints.values() for sp in sps]
        plant_pixels[mode] = sum(int((r.render(episode.camera, T, {}).labels > 0).sum()) for T in views)
        r.close()
    assert plant_pixels["repopa"] > plant_pixels["texture"] > 0, plant_pixels


def test_compare_reports_the_repopa_excess_of_a_helios_crop(tmp_path, cli):
    """``agrisim compare`` of a Helios crop (the five each show the excess in
    test_crop_runs_the_routine_with_organs_and_instances): RepOpa labels more pixels than the
    texture labels, the table says by how much, and every run counts the leaves it saw."""
    import csv
    import json

    from PIL import Image

    out = tmp_path / "compare"
    crops = ["tomato"]
    plants = ",".join(f"helios:{m}" for m in crops)
    code, _, err = cli(
        [
            "compare",
            "--plants",
            plants,
            "--workers",
            "2",
            "--out",
            str(out),
            "--physics",
            "kinematic",
            "--setpoints",
            "1x2",
            "--resolution",
            "160x90",
            "--shadow-samples",
            "0",
            "--set",
            "metrics.truth_samples=20000",
        ]
    )
    assert code == 0, err
    rows = {r["plant"]: r for r in csv.DictReader((out / "table.csv").open()) if r["label"] == "all"}
    assert set(rows) == {f"helios:{m}" for m in crops}
    for plant, row in rows.items():
        texture, repopa = int(row["pixels_texture"]), int(row["pixels_repopa"])
        assert repopa > texture > 0, plant
        assert float(row["pixels_pct"]) == pytest.approx(100 * (repopa / texture - 1), rel=1e-6)
    run = next(out.rglob("metrics.json")).parent
    metrics = json.loads((run / "metrics.json").read_text())
    ids: set[int] = set()
    for png in (run / "instances").glob("*.png"):
        ids |= set(np.unique(np.array(Image.open(png))).tolist())
    assert metrics["leaf_instances_seen"] == len(ids - {0}) > 0
