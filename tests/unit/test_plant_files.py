"""Plant assets in (glTF/GLB, OBJ+MTL) and ground-truth plants out (agrisim's GLB).

Assets are built in tmp by agrisim's own writer *and* by a second writer (trimesh's glTF and OBJ
exporters, hand-written OBJ/MTL/PNG), so the reader is not only checked against itself. Opacity is
checked geometrically: a card whose texture is half transparent must lose half its area
(:func:`agrisim.scene.texturing.cutaway_fraction`).
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image
from trimesh.visual.material import PBRMaterial, SimpleMaterial

from agrisim.errors import UserError
from agrisim.plugins.formats.plant_asset import load_plant
from agrisim.plugins.sinks.dataset.glb import export_glb
from agrisim.scene.model import Label, LabelTable, Material, Mesh
from agrisim.scene.texturing import cutaway_fraction, interpolate_uv, label_at, opaque, sample_surface

CARD_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.25  # a 25 cm square, z = 0
CARD_F = np.array([[0, 1, 2], [0, 2, 3]])
CARD_UV_GL = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)  # OpenGL/OBJ/trimesh: v up


def half_alpha(alpha_left: int = 255, alpha_right: int = 0, size: int = 8) -> np.ndarray:
    """RGBA texture: left half alpha ``alpha_left``, right half ``alpha_right``."""
    a = np.zeros((size, size, 4), np.uint8)
    a[..., 1] = 180
    a[:, : size // 2, 3] = alpha_left
    a[:, size // 2 :, 3] = alpha_right
    return a


def glb_json(path: Path) -> dict:
    data = path.read_bytes()
    (n,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20 : 20 + n])


def edit_glb(src: Path, dst: Path, edit) -> Path:
    """Copy a GLB, changing its JSON chunk with ``edit(doc)``."""
    data = src.read_bytes()
    (n,) = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20 : 20 + n])
    edit(doc)
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    rest = data[20 + n :]
    dst.write_bytes(
        struct.pack("<4sII", b"glTF", 2, 20 + len(j) + len(rest)) + struct.pack("<II", len(j), 0x4E4F534A) + j + rest
    )
    return dst


# ----------------------------------------------------------------------------------------------
# agrisim's own GLB
# ----------------------------------------------------------------------------------------------


def rich_mesh() -> tuple[Mesh, LabelTable]:
    rng = np.random.default_rng(1)
    n = 30
    vertices = rng.uniform(-0.3, 0.3, (n, 3)).astype(np.float32).astype(np.float64)
    faces = np.array([rng.choice(n, 3, replace=False) for _ in range(40)])
    uvs = rng.uniform(-0.5, 1.5, (n, 2)).astype(np.float32)
    albedo = rng.integers(0, 256, (16, 8, 4), dtype=np.uint8)
    labels_tex = rng.choice(np.array([1, 3], np.uint8), (16, 8))
    leaf = Material(
        "leaf",
        (0.9, 1.0, 0.8, 0.75),
        albedo=albedo,
        labels=labels_tex,
        alpha_mode="MASK",
        alpha_cutoff=0.4,
        back_color=(1.25, 1.5, 0.75),
        back_roughness=0.9,
    )
    stem = Material("stem", (0.3, 0.2, 0.1, 1.0), label=2, double_sided=False)
    petal = Material(
        "petal",
        albedo=albedo[:8],
        label=3,
        alpha_mode="BLEND",
        alpha_cutoff=0.25,
        roughness=0.3,
        metallic=0.5,
        transmission=rng.integers(0, 256, (4, 6, 3), dtype=np.uint8),
        metallic_roughness=rng.integers(0, 256, (8, 8, 3), dtype=np.uint8),
        normal_map=rng.integers(0, 256, (8, 4, 3), dtype=np.uint8),
        normal_scale=0.7,
    )
    face_material = np.array([0] * 10 + [1] * 10 + [0] * 5 + [2] * 15)
    inst = rng.integers(0, 7, 40).astype(np.uint16)
    colours = rng.random((len(vertices), 3)).astype(np.float32)
    mesh = Mesh("plant", vertices, faces, [leaf, stem, petal], face_material, uvs, inst, colours)
    table = LabelTable(
        [
            Label(0, "background", (0, 0, 0)),
            Label(1, "leaf", (0, 255, 0)),
            Label(2, "stem", (96, 0, 128)),
            Label(3, "flower_white", (0, 0, 255)),
        ]
    )
    return mesh, table


def test_round_trip_is_exact(tmp_path: Path) -> None:
    mesh, table = rich_mesh()
    path = tmp_path / "scene" / "plant.glb"
    export_glb(mesh, path, table)
    assert not [p for p in path.parent.iterdir() if p.name != "plant.glb"]  # atomic: no temp left
    plant = load_plant(path, place=False)
    m = plant.mesh
    assert np.array_equal(m.vertices, mesh.vertices)
    assert np.array_equal(m.faces, mesh.faces)
    assert np.array_equal(m.uvs, mesh.uvs)
    assert np.array_equal(m.face_material, mesh.face_material)
    assert np.array_equal(m.face_instance, mesh.face_instance)
    assert np.array_equal(m.colors, mesh.colors)
    assert len(m.materials) == len(mesh.materials)
    for a, b in zip(m.materials, mesh.materials, strict=True):
        assert (a.name, a.color, a.label, a.alpha_mode, a.alpha_cutoff, a.double_sided) == (
            b.name, b.color, b.label, b.alpha_mode, b.alpha_cutoff, b.double_sided
        )  # fmt: skip
        assert (a.roughness, a.metallic, a.transmittance, a.normal_scale, a.back_color, a.back_roughness) == (
            b.roughness,
            b.metallic,
            b.transmittance,
            b.normal_scale,
            b.back_color,
            b.back_roughness,
        )
        textures = ("albedo", "labels", "transmission", "metallic_roughness", "normal_map")
        for x, y in ((getattr(a, t), getattr(b, t)) for t in textures):
            assert (x is None) == (y is None)
            if x is not None:
                assert x.dtype == y.dtype and np.array_equal(x, y)
    assert plant.labels == table
    assert plant.organs


def test_export_is_standard_gltf(tmp_path: Path) -> None:
    """Another reader (trimesh) sees the geometry, y-up, and the alpha settings; the extras carry
    the label texture and the label table."""
    mesh, table = rich_mesh()
    path = tmp_path / "plant.glb"
    export_glb(mesh, path, table)
    doc = glb_json(path)
    assert doc["asset"]["version"] == "2.0"
    assert [e["name"] for e in doc["asset"]["extras"]["agrisim"]["labels"]] == [
        "background",
        "leaf",
        "stem",
        "flower_white",
    ]
    leaf = doc["materials"][0]
    assert leaf["alphaMode"] == "MASK" and leaf["alphaCutoff"] == 0.4 and leaf["doubleSided"] is True
    lt = leaf["extras"]["agrisim"]["label_texture"]
    assert lt != leaf["pbrMetallicRoughness"]["baseColorTexture"]["index"]
    assert doc["samplers"][doc["textures"][lt]["sampler"]]["magFilter"] == 9728  # nearest
    assert "alphaCutoff" not in doc["materials"][2]  # BLEND: cutoff only in extras

    scene = trimesh.load(path, process=False)
    verts = np.concatenate([g.vertices for g in scene.geometry.values()])
    yup = np.column_stack([mesh.vertices[:, 0], mesh.vertices[:, 2], -mesh.vertices[:, 1]])
    assert np.allclose(np.unique(verts, axis=0), np.unique(yup.astype(np.float32), axis=0))
    modes = {g.visual.material.name: g.visual.material.alphaMode for g in scene.geometry.values()}
    assert modes == {"leaf": "MASK", "stem": "OPAQUE", "petal": "BLEND"}


def test_interleaved_materials_group_by_material(tmp_path: Path) -> None:
    mesh, table = rich_mesh()
    fm = np.arange(len(mesh.faces)) % 3
    mesh = Mesh("plant", mesh.vertices, mesh.faces, mesh.materials, fm, mesh.uvs, mesh.face_instance)
    export_glb(mesh, tmp_path / "p.glb", table)
    m = load_plant(tmp_path / "p.glb", place=False).mesh
    key = lambda f, mat, inst: sorted(zip(map(tuple, f.tolist()), mat.tolist(), inst.tolist(), strict=True))  # noqa: E731
    assert key(m.faces, m.face_material, m.face_instance) == key(mesh.faces, mesh.face_material, mesh.face_instance)
    assert len(glb_json(tmp_path / "p.glb")["meshes"][0]["primitives"]) == 3


def test_export_refuses_labels_outside_the_table(tmp_path: Path) -> None:
    mesh, table = rich_mesh()
    with pytest.raises(ValueError, match="label ids"):
        export_glb(
            mesh, tmp_path / "p.glb", LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "leaf", (0, 255, 0))])
        )
    assert not (tmp_path / "p.glb").exists()


# ----------------------------------------------------------------------------------------------
# glTF from another writer (trimesh)
# ----------------------------------------------------------------------------------------------


def trimesh_card_glb(path: Path, albedo: np.ndarray, transform=None, **pbr) -> Path:
    mat = PBRMaterial(name="leaf", baseColorTexture=Image.fromarray(albedo, "RGBA"), **pbr)
    card = trimesh.Trimesh(
        CARD_V, CARD_F, process=False, visual=trimesh.visual.TextureVisuals(uv=CARD_UV_GL, material=mat)
    )
    scene = trimesh.Scene()
    scene.add_geometry(card, geom_name="leaf", transform=transform)
    scene.export(path)
    return path


def test_vertex_colours_written_by_trimesh(tmp_path: Path) -> None:
    """trimesh writes vertex colours as glTF's COLOR_0 of normalised bytes (RGBA): agrisim reads
    them as linear colours within 0..1, alpha dropped; a file without any has none."""
    rgba = np.array([[255, 0, 0, 255], [0, 128, 0, 255], [0, 0, 255, 10], [51, 102, 204, 255]], np.uint8)
    card = trimesh.Trimesh(CARD_V, CARD_F, process=False, vertex_colors=rgba)
    trimesh.Scene(card).export(tmp_path / "tinted.glb")
    mesh = load_plant(tmp_path / "tinted.glb", place=False).mesh
    by_position = {tuple(v): c for v, c in zip(mesh.vertices.round(6).tolist(), mesh.colors.tolist(), strict=True)}
    yup = CARD_V @ np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)  # the file's y up, read as z up
    for v, c in zip(yup.round(6).tolist(), rgba, strict=True):
        np.testing.assert_allclose(by_position[tuple(v)], c[:3] / 255.0, atol=1e-7)
    assert load_plant(trimesh_card_glb(tmp_path / "plain.glb", half_alpha()), place=False).mesh.colors is None


def test_trimesh_glb_alpha_mask_cutoff_is_honoured(tmp_path: Path) -> None:
    # Left half alpha 100/255 = 0.39: kept with the file's cutoff 0.3, cut with the default 0.5.
    T = trimesh.transformations.translation_matrix([0.1, 0.2, 0.3])
    path = trimesh_card_glb(
        tmp_path / "card.glb", half_alpha(100, 0), transform=T, alphaMode="MASK", alphaCutoff=0.3, doubleSided=True
    )
    plant = load_plant(path, place=False)
    mat = plant.mesh.materials[0]
    assert (mat.alpha_mode, mat.alpha_cutoff, mat.double_sided) == ("MASK", 0.3, True)
    assert cutaway_fraction(plant.mesh) == pytest.approx(0.5, abs=0.01)
    assert cutaway_fraction(load_plant(path, alpha_cutoff=0.5).mesh) == pytest.approx(1.0)
    # y-up -> z-up: (x, y, z) -> (x, -z, y), after the node's translation
    expected = (CARD_V + [0.1, 0.2, 0.3]) @ np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)
    assert np.allclose(np.sort(plant.mesh.vertices, axis=0), np.sort(expected, axis=0))
    assert plant.labels.labels[1] == Label(1, "plant", (0, 255, 0))
    assert set(label_at(mat, plant.mesh.uvs)) == {1}
    assert not plant.organs


def test_the_opaque_half_is_the_right_half(tmp_path: Path) -> None:
    """UV conventions: the texture's left (opaque) half lands on the card's x < 0.125 half."""
    path = trimesh_card_glb(tmp_path / "card.glb", half_alpha(255, 0), alphaMode="MASK")
    mesh = load_plant(path, place=False).mesh
    pts, faces, bary = sample_surface(mesh, 2000, np.random.default_rng(0))
    keep = opaque(mesh.materials[0], interpolate_uv(mesh, faces, bary))
    assert np.all(keep == (pts[:, 0] < 0.125))


def test_placement_puts_the_plant_on_the_soil_centre(tmp_path: Path) -> None:
    T = trimesh.transformations.translation_matrix([2.0, -1.0, 0.5])
    path = trimesh_card_glb(tmp_path / "card.glb", half_alpha(), transform=T)
    v = load_plant(path).mesh.vertices
    assert v[:, 2].min() == pytest.approx(0.0)
    assert (v[:, :2].min(axis=0) + v[:, :2].max(axis=0)) == pytest.approx([0.0, 0.0])
    assert np.ptp(v[:, 2]) == pytest.approx(0.25)  # the card stands up (y-up file)
    assert np.ptp(load_plant(path, up="z").mesh.vertices[:, 2]) == pytest.approx(0.0)


def two_material_glb(path: Path) -> Path:
    scene = trimesh.Scene()
    for name, dx in (("LeafMat.001", 0.0), ("Bark", 0.3)):
        mat = PBRMaterial(name=name, baseColorFactor=[0.2, 0.8, 0.2, 1.0])
        m = trimesh.Trimesh(
            CARD_V + [dx, 0, 0], CARD_F, process=False, visual=trimesh.visual.TextureVisuals(material=mat)
        )
        scene.add_geometry(m, geom_name=name)
    scene.export(path)
    return path


def test_material_labels(tmp_path: Path) -> None:
    path = two_material_glb(tmp_path / "two.glb")
    plant = load_plant(path, material_labels={"Leaf*": "leaf", "Bark": "stem"})
    assert [(lab.id, lab.name) for lab in plant.labels.labels] == [(0, "background"), (1, "leaf"), (2, "stem")]
    labels = {m.name: m.label for m in plant.mesh.materials}
    assert labels == {"LeafMat.001": 1, "Bark": 2}
    assert plant.organs
    bg = load_plant(path, material_labels={"Leaf*": "leaf", "*": "background"})
    assert {m.name: m.label for m in bg.mesh.materials} == {"LeafMat.001": 1, "Bark": 0}
    assert not bg.organs


def test_material_labels_must_cover_the_materials(tmp_path: Path) -> None:
    path = two_material_glb(tmp_path / "two.glb")
    with pytest.raises(UserError, match=r"two\.glb.*Bark.*no label"):
        load_plant(path, material_labels={"Leaf*": "leaf"})
    with pytest.raises(UserError, match=r"two\.glb.*'Lef\*'.*match no material.*LeafMat\.001"):
        load_plant(path, material_labels={"Lef*": "leaf", "*": "stem"})


# ----------------------------------------------------------------------------------------------
# OBJ + MTL + PNG
# ----------------------------------------------------------------------------------------------


def write_obj(
    folder: Path, mtl: str, obj_faces: str = "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n", textures: dict | None = None
) -> Path:
    """A y-up card (x right, y up) with two triangles, its MTL and textures."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, arr in (textures or {}).items():
        Image.fromarray(arr).save(folder / name)
    (folder / "card.mtl").write_text(mtl)
    verts = "".join(f"v {x} {y} {z}\n" for x, y, z in CARD_V)
    vts = "".join(f"vt {u} {v}\n" for u, v in CARD_UV_GL)
    (folder / "card.obj").write_text(f"# card\nmtllib card.mtl\n{verts}{vts}usemtl leaf\n{obj_faces}")
    return folder / "card.obj"


def test_obj_png_alpha_cuts_the_card(tmp_path: Path) -> None:
    path = write_obj(tmp_path, "newmtl leaf\nKd 0.8 0.8 0.8\nmap_Kd leaf.png\n", textures={"leaf.png": half_alpha()})
    plant = load_plant(path, place=False)
    mat = plant.mesh.materials[0]
    assert (mat.alpha_mode, mat.alpha_cutoff, mat.double_sided) == ("MASK", 0.5, True)
    assert np.array_equal(mat.albedo, half_alpha())
    assert cutaway_fraction(plant.mesh) == pytest.approx(0.5, abs=0.01)
    assert np.ptp(plant.mesh.vertices[:, 2]) == pytest.approx(0.25)  # y-up OBJ stands up
    # OBJ v is up, glTF v is down: the texture's bottom-left corner is at the card's (0, 0)
    corner = np.argmin(np.linalg.norm(plant.mesh.vertices, axis=1))
    assert plant.mesh.uvs[corner] == pytest.approx([0.0, 1.0])


def test_obj_map_d_with_options_and_spaces(tmp_path: Path) -> None:
    opacity = (half_alpha()[..., 3]).copy()
    rgb = np.full((8, 8, 3), 90, np.uint8)
    mtl = "newmtl leaf\nKd 1 1 1\nmap_Kd -s 1 1 1 my leaf.png\nmap_d -imfchan l opacity.png\n"
    path = write_obj(tmp_path, mtl, textures={"my leaf.png": rgb, "opacity.png": opacity})
    mesh = load_plant(path).mesh
    assert mesh.materials[0].alpha_mode == "MASK"
    assert cutaway_fraction(mesh) == pytest.approx(0.5, abs=0.01)


def test_obj_from_trimesh_exporter(tmp_path: Path) -> None:
    mat = SimpleMaterial(name="leaf", image=Image.fromarray(half_alpha(), "RGBA"))
    card = trimesh.Trimesh(
        CARD_V, CARD_F, process=False, visual=trimesh.visual.TextureVisuals(uv=CARD_UV_GL, material=mat)
    )
    (tmp_path / "t").mkdir()
    card.export(tmp_path / "t" / "card.obj")
    mesh = load_plant(tmp_path / "t" / "card.obj", up="z").mesh
    assert cutaway_fraction(mesh) == pytest.approx(0.5, abs=0.01)


def test_obj_polygons_negative_indices_and_plain_materials(tmp_path: Path) -> None:
    faces = "f -4/1 -3/2 -2/3 -1/4\nusemtl stem\nf 1 2 3\n"
    path = write_obj(tmp_path, "newmtl leaf\nKd 0 1 0\nnewmtl stem\nKd 0.4 0.2 0.1\nd 0.8\n", obj_faces=faces)
    mesh = load_plant(path, material_labels={"leaf": "leaf", "stem": "stem"}).mesh
    assert len(mesh.faces) == 3 and mesh.face_material.tolist() == [0, 0, 1]
    assert [m.label for m in mesh.materials] == [1, 2]
    assert mesh.materials[1].color == pytest.approx((0.4, 0.2, 0.1, 0.8)) and mesh.materials[1].alpha_mode == "BLEND"


# ----------------------------------------------------------------------------------------------
# Label textures
# ----------------------------------------------------------------------------------------------


def test_label_texture_of_ids(tmp_path: Path) -> None:
    path = write_obj(tmp_path, "newmtl leaf\nmap_Kd leaf.png\n", textures={"leaf.png": half_alpha(255, 255)})
    ids = np.ones((8, 8), np.uint8)
    ids[:, 4:] = 2
    Image.fromarray(ids, "L").save(tmp_path / "labels.png")
    plant = load_plant(path, label_texture=tmp_path / "labels.png", label_names={1: "leaf", 2: "stem"}, place=False)
    assert [(lab.id, lab.name, lab.color) for lab in plant.labels.labels[1:]] == [
        (1, "leaf", (0, 255, 0)),
        (2, "stem", (96, 0, 128)),
    ]
    mesh = plant.mesh
    pts, faces, bary = sample_surface(mesh, 2000, np.random.default_rng(0))
    lab = label_at(mesh.materials[0], interpolate_uv(mesh, faces, bary))
    assert np.all(lab == np.where(pts[:, 0] < 0.125, 1, 2))
    # it survives the GLB round trip
    export_glb(mesh, tmp_path / "out.glb", plant.labels)
    again = load_plant(tmp_path / "out.glb", place=False)
    assert np.array_equal(again.mesh.materials[0].labels, ids) and again.labels == plant.labels


def test_label_texture_of_paper_colours(tmp_path: Path) -> None:
    path = trimesh_card_glb(tmp_path / "card.glb", half_alpha(255, 255))
    colours = np.zeros((8, 8, 3), np.uint8)
    colours[:, :4] = (0, 255, 0)
    colours[:, 4:6] = (0, 0, 255)
    colours[:, 6:] = (10, 20, 30)
    Image.fromarray(colours, "RGB").save(tmp_path / "seg.png")
    plant = load_plant(path, label_texture=tmp_path / "seg.png", label_names={"#0A141E": "bud"})
    assert [(lab.id, lab.name) for lab in plant.labels.labels] == [
        (0, "background"),
        (1, "leaf"),
        (2, "flower_white"),
        (3, "bud"),
    ]
    lab = plant.mesh.materials[0].labels
    assert lab[0, 0] == 1 and lab[0, 4] == 2 and lab[0, 7] == 3


# ----------------------------------------------------------------------------------------------
# Bad assets: one clear UserError naming the file
# ----------------------------------------------------------------------------------------------


def own_card_glb(path: Path) -> Path:
    mat = Material("leaf", albedo=half_alpha(), alpha_mode="MASK", label=1)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    export_glb(
        Mesh("card", CARD_V, CARD_F, [mat], np.zeros(2, int), uv),
        path,
        LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "plant", (0, 255, 0))]),
    )
    return path


def expect_error(path, pattern: str, **kw) -> None:
    with pytest.raises(UserError) as err:
        load_plant(path, **kw)
    msg = str(err.value)
    assert Path(path).name in msg, msg
    assert "\n" not in msg
    assert re.search(pattern, msg), msg


def test_own_card_cuts_half(tmp_path: Path) -> None:
    assert cutaway_fraction(load_plant(own_card_glb(tmp_path / "card.glb")).mesh) == pytest.approx(0.5, abs=0.01)


def test_missing_and_unreadable_files(tmp_path: Path) -> None:
    expect_error(tmp_path / "nope.glb", "no such file")
    (tmp_path / "dir.glb").mkdir()
    expect_error(tmp_path / "dir.glb", "directory")
    (tmp_path / "notes.txt").write_text("hello")
    expect_error(tmp_path / "notes.txt", "not a plant mesh format")
    Image.fromarray(half_alpha()).save(tmp_path / "image.png")
    (tmp_path / "fake.glb").write_bytes((tmp_path / "image.png").read_bytes())
    expect_error(tmp_path / "fake.glb", "not a binary glTF")
    (tmp_path / "fake.gltf").write_text("{ not json")
    expect_error(tmp_path / "fake.gltf", "not a glTF file")
    (tmp_path / "words.obj").write_text("hello world\nthis is prose\n")
    expect_error(tmp_path / "words.obj", "not a mesh")
    (tmp_path / "blob.obj").write_bytes(b"\x00\x01\x02" * 100)
    expect_error(tmp_path / "blob.obj", "not a mesh")


def test_no_triangles_and_nan(tmp_path: Path) -> None:
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    expect_error(tmp_path / "points.obj", "no triangles")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    expect_error(tmp_path / "nan.obj", "NaN")
    own_card_glb(tmp_path / "card.glb")
    edit_glb(tmp_path / "card.glb", tmp_path / "lines.glb", lambda d: d["meshes"][0]["primitives"][0].update(mode=1))
    expect_error(tmp_path / "lines.glb", "no triangles")
    edit_glb(tmp_path / "card.glb", tmp_path / "nomesh.glb", lambda d: d.update(meshes=[], nodes=[{}]))
    expect_error(tmp_path / "nomesh.glb", "not a mesh")
    edit_glb(
        tmp_path / "card.glb", tmp_path / "nanT.glb", lambda d: d["nodes"][0].update(translation=[0, float("nan"), 0])
    )
    expect_error(tmp_path / "nanT.glb", "NaN")


def test_uv_problems(tmp_path: Path) -> None:
    own_card_glb(tmp_path / "card.glb")
    edit_glb(
        tmp_path / "card.glb",
        tmp_path / "nouv.glb",
        lambda d: d["meshes"][0]["primitives"][0]["attributes"].pop("TEXCOORD_0"),
    )
    expect_error(tmp_path / "nouv.glb", "no UVs")

    def short_uvs(d):
        d["accessors"][d["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]]["count"] = 3

    edit_glb(tmp_path / "card.glb", tmp_path / "shortuv.glb", short_uvs)
    expect_error(tmp_path / "shortuv.glb", "3 UVs for 4 vertices")

    obj = write_obj(
        tmp_path / "a", "newmtl leaf\nmap_Kd leaf.png\n", obj_faces="f 1 2 3\n", textures={"leaf.png": half_alpha()}
    )
    expect_error(obj, "no UVs")
    obj = write_obj(
        tmp_path / "b",
        "newmtl leaf\nmap_Kd leaf.png\n",
        obj_faces="f 1/1 2/9 3/3\n",
        textures={"leaf.png": half_alpha()},
    )
    expect_error(obj, "texture coordinate 9, but the file has 4")


def test_texture_problems(tmp_path: Path) -> None:
    obj = write_obj(tmp_path / "a", "newmtl leaf\nmap_Kd leaf.png\n")
    (tmp_path / "a" / "leaf.png").write_text("not a png")
    expect_error(obj, r"material library 'card\.mtl': texture 'leaf\.png': not an image")
    obj = write_obj(tmp_path / "b", "newmtl leaf\nmap_Kd missing.png\n")
    expect_error(obj, "missing.png' not found")
    obj = write_obj(tmp_path / "c", "")
    (tmp_path / "c" / "card.mtl").unlink()
    expect_error(obj, "material library 'card.mtl' not found")

    own_card_glb(tmp_path / "card.glb")
    data = bytearray((tmp_path / "card.glb").read_bytes())
    i = data.find(b"\x89PNG")
    data[i : i + 8] = b"garbage!"
    (tmp_path / "badimg.glb").write_bytes(bytes(data))
    expect_error(tmp_path / "badimg.glb", "image 0.*not an image")


def test_label_texture_problems(tmp_path: Path) -> None:
    glb = own_card_glb(tmp_path / "card.glb")
    Image.fromarray(np.ones((4, 4), np.uint8), "L").save(tmp_path / "small.png")
    with pytest.raises(
        UserError, match=r"small\.png: label texture is 4x4 but the albedo of material 'leaf' in .*card\.glb is 8x8"
    ):
        load_plant(glb, label_texture=tmp_path / "small.png")
    photo = np.random.default_rng(0).integers(0, 256, (16, 16, 3), dtype=np.uint8)
    Image.fromarray(photo, "RGB").save(tmp_path / "photo.png")
    with pytest.raises(UserError, match=r"photo\.png: label texture has \d+ distinct colours"):
        load_plant(glb, label_texture=tmp_path / "photo.png")
    Image.fromarray(np.full((8, 8), 1000, np.uint16)).save(tmp_path / "wide.png")
    with pytest.raises(UserError, match=r"wide\.png: label ids must be within 0\.\.255"):
        load_plant(glb, label_texture=tmp_path / "wide.png")
    (tmp_path / "text.png").write_text("hello")
    with pytest.raises(UserError, match=r"text\.png: not an image"):
        load_plant(glb, label_texture=tmp_path / "text.png")
    with pytest.raises(UserError, match=r"card\.glb: give either"):
        load_plant(glb, label_texture=tmp_path / "small.png", material_labels={"*": "leaf"})
    untextured = two_material_glb(tmp_path / "two.glb")
    expect_error(untextured, "no UVs", label_texture=tmp_path / "small.png")


def test_too_big_suggests_centimetres(tmp_path: Path) -> None:
    card = trimesh.Trimesh(CARD_V * 600, CARD_F, process=False)  # 150 "m": an asset in cm
    card.export(tmp_path / "big.glb")
    expect_error(tmp_path / "big.glb", r"150 m across.*centimetres.*scale=0\.01")
    assert np.ptp(load_plant(tmp_path / "big.glb", scale=0.01).mesh.vertices[:, 0]) == pytest.approx(1.5)


def test_refused_extensions(tmp_path: Path) -> None:
    own_card_glb(tmp_path / "card.glb")
    edit_glb(
        tmp_path / "card.glb",
        tmp_path / "draco.glb",
        lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]),
    )
    expect_error(tmp_path / "draco.glb", "Draco")


def test_root_refuses_escapes(tmp_path: Path) -> None:
    root = tmp_path / "assets"
    root.mkdir()
    own_card_glb(tmp_path / "outside.glb")
    own_card_glb(root / "inside.glb")
    assert load_plant("inside.glb", root=root).mesh.faces.shape == (2, 3)
    with pytest.raises(UserError, match=r"\.\./outside\.glb: outside the asset root"):
        load_plant("../outside.glb", root=root)
    with pytest.raises(UserError, match="outside the asset root"):
        load_plant(tmp_path / "outside.glb", root=root)
    os.symlink(tmp_path / "outside.glb", root / "link.glb")
    with pytest.raises(UserError, match=r"link\.glb: a symlink out of the asset root"):
        load_plant("link.glb", root=root)
    # files an asset refers to are held to the root too
    write_obj(tmp_path / "tex", "", textures={"leaf.png": half_alpha()})
    obj = write_obj(root / "sub", "newmtl leaf\nmap_Kd ../../tex/leaf.png\n")
    with pytest.raises(
        UserError,
        match=r"card\.obj: material library 'card\.mtl': texture '\.\./\.\./tex/leaf\.png': outside the asset root",
    ):
        load_plant(obj, root=root)
    assert load_plant(obj).mesh.materials[0].albedo is not None  # without a root it is fine


# ----------------------------------------------------------------------------------------------
# More glTF: external and embedded buffers, texture transforms, mirrored nodes
# ----------------------------------------------------------------------------------------------


def trimesh_card(albedo: np.ndarray) -> trimesh.Trimesh:
    mat = PBRMaterial(name="leaf", baseColorTexture=Image.fromarray(albedo, "RGBA"), alphaMode="MASK")
    return trimesh.Trimesh(
        CARD_V, CARD_F, process=False, visual=trimesh.visual.TextureVisuals(uv=CARD_UV_GL, material=mat)
    )


def test_gltf_with_external_and_embedded_buffers(tmp_path: Path) -> None:
    folder = tmp_path / "assets" / "card"
    folder.mkdir(parents=True)
    for name, data in trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh_card(half_alpha()))).items():
        (folder / name).write_bytes(data)
    mesh = load_plant(folder / "model.gltf", root=tmp_path / "assets").mesh
    assert cutaway_fraction(mesh) == pytest.approx(0.5, abs=0.01)

    embedded = trimesh.exchange.gltf.export_gltf(trimesh.Scene(trimesh_card(half_alpha())), embed_buffers=True)
    (tmp_path / "embedded.gltf").write_bytes(embedded["model.gltf"])
    assert cutaway_fraction(load_plant(tmp_path / "embedded.gltf").mesh) == pytest.approx(0.5, abs=0.01)

    doc = json.loads((folder / "model.gltf").read_text())
    doc["buffers"][0]["uri"] = "../../outside.bin"
    (tmp_path / "outside.bin").write_bytes((folder / "gltf_buffer_0.bin").read_bytes())
    (folder / "escape.gltf").write_text(json.dumps(doc))
    with pytest.raises(UserError, match=r"escape\.gltf: buffer 0 '\.\./\.\./outside\.bin': outside the asset root"):
        load_plant(folder / "escape.gltf", root=tmp_path / "assets")
    doc["buffers"][0]["uri"] = "https://example.com/x.bin"
    (folder / "remote.gltf").write_text(json.dumps(doc))
    expect_error(folder / "remote.gltf", "not a local file")


def test_texture_transform_moves_the_cut(tmp_path: Path) -> None:
    own_card_glb(tmp_path / "card.glb")

    def shift(d):
        d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = {
            "KHR_texture_transform": {"offset": [0.5, 0.0]}
        }

    mesh = load_plant(edit_glb(tmp_path / "card.glb", tmp_path / "shifted.glb", shift), place=False).mesh
    pts, faces, bary = sample_surface(mesh, 2000, np.random.default_rng(0))
    assert np.all(opaque(mesh.materials[0], interpolate_uv(mesh, faces, bary)) == (pts[:, 0] >= 0.125))


def test_normal_and_metallic_roughness_textures_from_trimesh(tmp_path: Path) -> None:
    """trimesh writes glTF's normal and metallic-roughness textures and flips its OpenGL UVs
    (v up) to glTF's; agrisim reads the texels as written, and the card's UVs come out in
    glTF's usual layout (unmirrored: the normal map's y is up the image)."""
    from agrisim.plugins.render.mitsuba.materials import mirrored_faces

    rng = np.random.default_rng(5)
    normals = rng.integers(0, 256, (8, 8, 3), dtype=np.uint8)
    mr = rng.integers(0, 256, (8, 8, 3), dtype=np.uint8)
    path = trimesh_card_glb(
        tmp_path / "card.glb",
        half_alpha(),
        normalTexture=Image.fromarray(normals, "RGB"),
        metallicRoughnessTexture=Image.fromarray(mr, "RGB"),
        roughnessFactor=0.5,
        metallicFactor=0.25,
    )
    mesh = load_plant(path, place=False).mesh
    mat = mesh.materials[0]
    assert np.array_equal(mat.normal_map, normals) and np.array_equal(mat.metallic_roughness, mr)
    assert (mat.roughness, mat.metallic) == (0.5, 0.25)
    assert not mirrored_faces(mesh.faces, mesh.uvs).any()
    flipped = mesh.uvs.copy()
    flipped[:, 0] = 1.0 - flipped[:, 0]
    assert mirrored_faces(mesh.faces, flipped).all()


def test_diffuse_transmission_extension(tmp_path: Path) -> None:
    """KHR_materials_diffuse_transmission: a fraction f of the diffuse light goes through with
    its own colour: the transmission texture holds f x colour (sRGB), the reflected albedo
    keeps 1 - f, texel by texel where f has a texture (here the albedo's alpha: f on the
    opaque half, 0 on the other)."""
    from agrisim.scene.colour import linear_to_srgb, srgb_to_linear

    own_card_glb(tmp_path / "card.glb")
    ext = {"diffuseTransmissionFactor": 0.4, "diffuseTransmissionColorFactor": [0.5, 1.0, 0.2]}

    def constant(d):
        d["materials"][0]["extensions"] = {"KHR_materials_diffuse_transmission": dict(ext)}

    mat = load_plant(edit_glb(tmp_path / "card.glb", tmp_path / "c.glb", constant), place=False).mesh.materials[0]
    expected = np.round(linear_to_srgb(0.4 * np.array([0.5, 1.0, 0.2])) * 255.0)
    assert mat.transmittance is None and mat.transmission.shape == (1, 1, 3)
    assert np.array_equal(mat.transmission[0, 0], expected)
    assert np.allclose(mat.color[:3], 0.8 * 0.6) and np.array_equal(
        mat.albedo, half_alpha()
    )  # (0.8: the card's colour)

    def textured(d):
        d["materials"][0]["extensions"] = {
            "KHR_materials_diffuse_transmission": dict(ext, diffuseTransmissionTexture={"index": 0})
        }

    mat = load_plant(edit_glb(tmp_path / "card.glb", tmp_path / "t.glb", textured), place=False).mesh.materials[0]
    source = half_alpha()
    f = 0.4 * source[..., 3] / 255.0
    assert np.allclose(mat.color[:3], 0.8)
    kept = np.round(linear_to_srgb(srgb_to_linear(source[..., :3] / 255.0) * (1.0 - f)[..., None]) * 255.0)
    assert np.array_equal(mat.albedo[..., :3], kept) and np.array_equal(mat.albedo[..., 3], source[..., 3])
    through = np.round(linear_to_srgb(f[..., None] * np.array([0.5, 1.0, 0.2])) * 255.0)
    assert np.array_equal(mat.transmission, through)


def test_textures_on_other_uvs_are_refused(tmp_path: Path) -> None:
    own_card_glb(tmp_path / "card.glb")

    def other_set(d):
        d["materials"][0]["normalTexture"] = {"index": 0, "texCoord": 1}

    expect_error(
        edit_glb(tmp_path / "card.glb", tmp_path / "n.glb", other_set), r"normalTexture uses other texture coordinates"
    )


def test_mirrored_node_keeps_the_winding(tmp_path: Path) -> None:
    own_card_glb(tmp_path / "card.glb")
    plain = load_plant(tmp_path / "card.glb", place=False).mesh
    mirrored = load_plant(
        edit_glb(tmp_path / "card.glb", tmp_path / "m.glb", lambda d: d["nodes"][0].update(scale=[-1, 1, 1])),
        place=False,
    ).mesh

    def normal(m: Mesh) -> np.ndarray:
        a, b, c = (m.vertices[m.faces[0, i]] for i in range(3))
        return np.cross(b - a, c - a)

    assert np.allclose(mirrored.vertices[:, 0], -plain.vertices[:, 0])
    assert normal(mirrored) @ normal(plain) > 0  # same side faces the same way


def test_label_names_need_a_label_texture(tmp_path: Path) -> None:
    expect_error(own_card_glb(tmp_path / "card.glb"), "label names", label_names={1: "leaf"})


def test_handwritten_gltf_strip_sparse_normalized(tmp_path: Path) -> None:
    """A third writer: glTF JSON by hand, with a triangle strip, a sparse accessor, normalized
    8-bit UVs and an embedded data-URI PNG."""
    import base64
    import io

    pos = np.array([[0, 0, 0], [1, 0, 0], [9, 9, 9], [0, 1, 0]], "<f4") * 0.25  # vertex 2 fixed by sparse
    uv = np.array([[0, 0], [255, 0], [255, 255], [0, 255]], np.uint8)
    strip = np.array([0, 1, 3, 2], "<u2")
    sparse_idx = np.array([2, 0, 0, 0], np.uint8)  # 1 index + padding
    sparse_val = np.array([0.25, 0.25, 0.0], "<f4")
    blob = pos.tobytes() + uv.tobytes() + strip.tobytes() + sparse_idx.tobytes() + sparse_val.tobytes()
    png = io.BytesIO()
    Image.fromarray(half_alpha(), "RGBA").save(png, format="PNG")
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [
            {"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 8},
            {"buffer": 0, "byteOffset": 56, "byteLength": 8},
            {"buffer": 0, "byteOffset": 64, "byteLength": 1},
            {"buffer": 0, "byteOffset": 68, "byteLength": 12},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "sparse": {
                    "count": 1,
                    "indices": {"bufferView": 3, "componentType": 5121},
                    "values": {"bufferView": 4},
                },
            },
            {"bufferView": 1, "componentType": 5121, "normalized": True, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 4, "type": "SCALAR"},
        ],  # fmt: skip
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode()}],
        "textures": [{"source": 0}],
        "materials": [
            {"name": "leaf", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "alphaMode": "MASK"}
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "mode": 5, "material": 0}]}
        ],
        "nodes": [{"mesh": 0}],
    }
    (tmp_path / "hand.gltf").write_text(json.dumps(doc))
    mesh = load_plant(tmp_path / "hand.gltf", place=False).mesh
    assert mesh.vertices[2] == pytest.approx([0.25, 0.0, 0.25])  # sparse value, y-up -> z-up
    assert mesh.faces.tolist() == [[0, 1, 3], [3, 1, 2]]  # strip, winding kept
    assert mesh.uvs.tolist() == [[0, 0], [1, 0], [1, 1], [0, 1]]
    assert mesh.materials[0].double_sided is False  # the glTF default
    assert cutaway_fraction(mesh) == pytest.approx(0.5, abs=0.01)


def test_embedded_label_texture_must_match_the_albedo(tmp_path: Path) -> None:
    mesh, table = rich_mesh()
    export_glb(mesh, tmp_path / "p.glb", table)

    def swap(d):  # the leaf's label texture -> the petal's albedo texture (8x8 RGBA, albedo 16x8)
        d["materials"][0]["extras"]["agrisim"]["label_texture"] = d["materials"][2]["pbrMetallicRoughness"][
            "baseColorTexture"
        ]["index"]

    expect_error(
        edit_glb(tmp_path / "p.glb", tmp_path / "bad.glb", swap), "label texture .* not a single-channel image"
    )

    leaf = dataclasses.replace(mesh.materials[0], labels=np.ones((4, 4), np.uint8))  # albedo is 16x8
    export_glb(
        Mesh("plant", mesh.vertices, mesh.faces, [leaf], np.zeros(len(mesh.faces), int), mesh.uvs),
        tmp_path / "s.glb",
        table,
    )
    expect_error(tmp_path / "s.glb", r"label texture .* is 4x4 but its albedo is 8x16")
