"""glTF reading and writing where agrisim does what pygltflib leaves to it: a second UV set, the
binary container's header, JSON that is not glTF, and extras pygltflib's writer would drop.
Truth: where opacity cuts a card (geometry), and the files' own bytes."""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np
import pytest
from test_plant_files import edit_glb, expect_error, own_card_glb

from agrisim.plugins.formats.plant_asset import load_plant
from agrisim.plugins.sinks.dataset.glb import export_glb
from agrisim.plugins.sinks.dataset.scene_glb import scene_glb_bytes
from agrisim.scene.model import LabelTable, Light, Material, Mesh, Scene
from agrisim.scene.texturing import interpolate_uv, opaque, sample_surface


def test_textures_on_the_second_uv_set(tmp_path: Path) -> None:
    """``texCoord: 1`` reads TEXCOORD_1: with the card's UVs there and their mirror image in
    TEXCOORD_0, the opaque (left) half of the texture stays on the card's x < 0.125 half."""
    own_card_glb(tmp_path / "card.glb")
    mirrored = np.array([[1, 1], [0, 1], [0, 0], [1, 0]], "<f4")  # the card's UVs with u -> 1 - u

    def second_set(d: dict) -> None:
        uri = "data:application/octet-stream;base64," + base64.b64encode(mirrored.tobytes()).decode()
        d["buffers"].append({"byteLength": mirrored.nbytes, "uri": uri})
        d["bufferViews"].append({"buffer": len(d["buffers"]) - 1, "byteLength": mirrored.nbytes})
        d["accessors"].append(
            {"bufferView": len(d["bufferViews"]) - 1, "componentType": 5126, "count": 4, "type": "VEC2"}
        )
        attrs = d["meshes"][0]["primitives"][0]["attributes"]
        attrs["TEXCOORD_1"], attrs["TEXCOORD_0"] = attrs["TEXCOORD_0"], len(d["accessors"]) - 1
        d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = 1

    for name, edit in (("set0.glb", lambda d: None), ("set1.glb", second_set)):
        mesh = load_plant(edit_glb(tmp_path / "card.glb", tmp_path / name, edit), place=False).mesh
        pts, faces, bary = sample_surface(mesh, 2000, np.random.default_rng(0))
        keep = opaque(mesh.materials[0], interpolate_uv(mesh, faces, bary))
        assert np.all(keep == (pts[:, 0] < 0.125)), name


def test_glb_header_problems(tmp_path: Path) -> None:
    """What pygltflib only warns about or reads past: another container version, a short file."""
    data = own_card_glb(tmp_path / "card.glb").read_bytes()
    (tmp_path / "v1.glb").write_bytes(data[:4] + struct.pack("<I", 1) + data[8:])
    expect_error(tmp_path / "v1.glb", r"binary glTF version 1 is not supported")
    (tmp_path / "short.glb").write_bytes(data[: len(data) - 100])
    expect_error(tmp_path / "short.glb", rf"truncated binary glTF \({len(data) - 100} of {len(data)} bytes\)")
    (tmp_path / "stub.glb").write_bytes(data[:16])
    expect_error(tmp_path / "stub.glb", r"truncated binary glTF \(shorter than its header\)")


def test_json_that_is_not_gltf(tmp_path: Path) -> None:
    for i, doc in enumerate(([1, 2, 3], {"asset": {"version": "2.0"}, "nodes": [5]}, {"accessors": 7})):
        (tmp_path / f"odd{i}.gltf").write_text(json.dumps(doc))
        expect_error(tmp_path / f"odd{i}.gltf", r"not a glTF file \(its JSON does not have glTF's structure")


def test_extras_the_writer_would_drop_are_refused(tmp_path: Path) -> None:
    """pygltflib's JSON writer deletes empty values at any depth of ``extras``; a scene without
    lights (``"lights": []``) would then read back as a malformed scene, so it is refused when
    written. With a light it is written."""
    quad = Mesh(
        "floor",
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0]], float),
        np.array([[0, 1, 2]]),
        [Material("m", label=0)],
        np.zeros(1, int),
    )
    with pytest.raises(ValueError, match=r"asset: extras key 'agrisim\.lights' is empty"):
        scene_glb_bytes(Scene([quad], [], LabelTable()))
    lit = Scene([quad], [Light("l", "point", np.array([0.0, 0, 2]), np.array([0.0, 0, -1]))], LabelTable())
    assert scene_glb_bytes(lit)[:4] == b"glTF"


def test_what_agrisim_writes_is_valid_gltf(tmp_path: Path) -> None:
    """The JSON of agrisim's plant GLB and scene GLB passes the Khronos glTF 2.0 schema (the copy
    trimesh ships), extras and all."""
    from test_plant_files import glb_json, rich_mesh
    from trimesh.exchange.gltf import validate

    mesh, table = rich_mesh()
    export_glb(mesh, tmp_path / "plant.glb", table)
    validate(glb_json(tmp_path / "plant.glb"))
    light = Light("l", "point", np.array([0.0, 0, 2]), np.array([0.0, 0, -1]))
    (tmp_path / "lab.glb").write_bytes(scene_glb_bytes(Scene([mesh], [light], table, plant="plant")))
    validate(glb_json(tmp_path / "lab.glb"))
