"""glTF through pygltflib against the hand-written reader and writer it replaced: the same files
read, the same plants out. Prints a table per input set and the differences it finds (none is the
expected answer); exits 1 if any.

    python bench/gltf_equality.py                     # species, scenes, user glTF, 6 Helios crops
    python bench/gltf_equality.py --helios all        # every Helios crop model (minutes)
    python bench/gltf_equality.py --why-not-trimesh   # also: what trimesh's loaders make of the inputs
    python bench/gltf_equality.py --old 1c06aa1       # the hand-written code of that commit

The old code is ``core/files/{gltf,glb,scene_glb}.py`` of ``--old`` (default: the commit before
the one that added ``core/files/gltf_document.py``, or HEAD while that is not committed), loaded
from git as modules of their own. Inputs:

* the ten procedural species (seed 0) and Helios crops: ``plant.glb`` as the old and as the new
  writer write it, each read by the old and by the new reader (four reads that must agree: files of
  an older agrisim read by this one, and the other way round), then loaded as plants;
* ``scene/lab.glb`` of the lab with each species (and its arms), written and read both ways;
* the user glTF files that ``tests/unit/test_plant_files.py`` builds (trimesh's writer, edited
  agrisim GLBs: alphaCutoff, BLEND, KHR_texture_transform, KHR_materials_diffuse_transmission,
  KHR_materials_pbrSpecularGlossiness, normal and metallic-roughness maps, TEXCOORD_1, node
  translation, rotation, matrix and mirroring, strips, fans, sparse and normalized accessors,
  external and embedded buffers) and the broken ones: the same plant, or the same error message.

Compared: vertices (y-up, and z-up after loading), triangles and their order, UVs and which vertices
have them, per-face materials and leaf instances, every material field and texture (dtype and
texels), the label table, and the cut-out behaviour: which of 20,000 surface samples opacity keeps
and the label each one gets.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import importlib.util
import io
import json
import struct
import subprocess
import sys
import tempfile
import time
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.files import glb as new_glb
from agrisim.files import gltf as new_gltf
from agrisim.files import plant_asset, scene_glb
from agrisim.scene.model import Material, Mesh, Plant
from agrisim.scene.texturing import labels_at_samples, opaque_samples, sample_surface

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "unit"))  # the user-glTF inputs of test_plant_files

MATERIAL_FIELDS = [f.name for f in dataclasses.fields(Material)]
HELIOS_DEFAULT = ["bean", "tomato", "strawberry", "maize", "butterlettuce", "wheat"]


# -- the old code -----------------------------------------------------------------------------------


def default_old() -> str:
    added = subprocess.run(
        ["git", "log", "-1", "--format=%H", "--diff-filter=A", "--", "core/files/gltf_document.py"],
        cwd=REPO, capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    return f"{added}^" if added else "HEAD"


def load_old(rev: str) -> types.SimpleNamespace:
    """gltf, glb and scene_glb of ``rev`` as modules _old_gltf, _old_glb, _old_scene_glb."""

    def module(name: str, path: str, imports: dict[str, str]) -> types.ModuleType:
        src = subprocess.run(
            ["git", "show", f"{rev}:{path}"], cwd=REPO, capture_output=True, text=True, check=True
        ).stdout
        for a, b in imports.items():
            assert a in src, (path, a)
            src = src.replace(a, b)
        spec = importlib.util.spec_from_loader(name, loader=None)
        mod = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        sys.modules[name] = mod
        exec(compile(src, f"{rev}:{path}", "exec"), mod.__dict__)  # noqa: S102  (agrisim's own source, from git)
        return mod

    gltf = module("_old_gltf", "core/files/gltf.py", {})
    glb = module("_old_glb", "core/files/glb.py", {"from agrisim.plugins.formats.gltf import": "from _old_gltf import"})
    scene = module(
        "_old_scene_glb",
        "core/files/scene_glb.py",
        {
            "from agrisim.plugins.sinks.dataset.glb import": "from _old_glb import",
            "from agrisim.plugins.formats.gltf import": "from _old_gltf import",
        },
    )
    return types.SimpleNamespace(gltf=gltf, glb=glb, scene_glb=scene, rev=rev)


# -- comparing ------------------------------------------------------------------------------------


def diff_arrays(what: str, a: Any, b: Any) -> list[str]:
    if a is None or b is None:
        return (
            []
            if a is None and b is None
            else [f"{what}: {'None' if a is None else 'set'} vs {'None' if b is None else 'set'}"]
        )
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return [f"{what}: {a.dtype}{a.shape} vs {b.dtype}{b.shape}"]
    if not np.array_equal(a, b, equal_nan=a.dtype.kind == "f"):
        return [f"{what}: {int(np.sum(a != b))} of {a.size} values differ"]
    return []


def diff_materials(what: str, ma: list[Material], mb: list[Material]) -> list[str]:
    if len(ma) != len(mb):
        return [f"{what}: {len(ma)} vs {len(mb)} materials"]
    out = []
    for i, (a, b) in enumerate(zip(ma, mb, strict=True)):
        for f in MATERIAL_FIELDS:
            x, y = getattr(a, f), getattr(b, f)
            if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
                out += diff_arrays(f"{what}[{i}].{f}", x, y)
            elif x != y or type(x) is not type(y):
                out.append(f"{what}[{i}].{f}: {x!r} vs {y!r}")
    return out


def diff_raw(a: Any, b: Any) -> list[str]:
    out = []
    for f in ("positions", "faces", "face_material", "uvs", "has_uv", "face_instance"):
        out += diff_arrays(f, getattr(a, f), getattr(b, f))
    out += diff_materials("materials", a.materials, b.materials)
    if a.texture_names != b.texture_names:
        out.append(f"texture_names: {a.texture_names} vs {b.texture_names}")
    if a.labels != b.labels:
        out.append("label tables differ")
    return out


def diff_mesh(what: str, a: Mesh, b: Mesh, samples: int = 20_000) -> list[str]:
    out = [] if a.name == b.name else [f"{what}.name: {a.name!r} vs {b.name!r}"]
    for f in ("vertices", "faces", "face_material", "uvs", "face_instance"):
        out += diff_arrays(f"{what}.{f}", getattr(a, f), getattr(b, f))
    out += diff_materials(f"{what}.materials", a.materials, b.materials)
    if not out and samples and len(a.faces) and a.areas.sum() > 0:  # the cut-outs and labels a renderer sees
        _, faces, bary = sample_surface(a, samples, np.random.default_rng(0))
        out += diff_arrays(f"{what} opacity at samples", opaque_samples(a, faces, bary), opaque_samples(b, faces, bary))
        out += diff_arrays(
            f"{what} labels at samples", labels_at_samples(a, faces, bary), labels_at_samples(b, faces, bary)
        )
    return out


def diff_plant(a: Plant, b: Plant) -> list[str]:
    out = diff_mesh("plant", a.mesh, b.mesh)
    if a.labels != b.labels:
        out.append("plant label tables differ")
    if (a.organs, a.notes) != (b.organs, b.notes):
        out.append(f"organs/notes: {(a.organs, a.notes)} vs {(b.organs, b.notes)}")
    return out


def load_with(read_gltf: Callable[..., Any], path: Path, **kw: Any) -> Plant:
    """load_plant with ``read_gltf`` as its glTF reader."""
    saved = plant_asset.read_gltf
    plant_asset.read_gltf = read_gltf
    try:
        return plant_asset.load_plant(path, **kw)
    finally:
        plant_asset.read_gltf = saved


def outcome(fn: Callable[[], Any]) -> Any:
    try:
        return fn()
    except Exception as e:  # noqa: BLE001  (an error message is an outcome to compare)
        return f"{type(e).__name__}: {e}"


def glb_parts(data: bytes) -> tuple[dict, bytes]:
    (n,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20 : 20 + n]), data[20 + n + 8 :]


# -- input sets -------------------------------------------------------------------------------------


def compare_written(old: types.SimpleNamespace, name: str, mesh: Mesh, labels: Any, tmp: Path, row: dict) -> list[str]:
    """plant.glb of ``mesh`` by the old and the new writer, each read by both readers and loaded."""
    t = time.perf_counter()
    b_old = old.glb.glb_bytes(mesh, labels)
    row["write old s"] = time.perf_counter() - t
    t = time.perf_counter()
    b_new = new_glb.glb_bytes(mesh, labels)
    row["write new s"] = time.perf_counter() - t
    p_old, p_new = tmp / "old" / f"{name}.glb", tmp / "new" / f"{name}.glb"  # one name: a plant is named after its file
    p_old.parent.mkdir(exist_ok=True)
    p_new.parent.mkdir(exist_ok=True)
    p_old.write_bytes(b_old)
    p_new.write_bytes(b_new)
    out = []
    (j_old, bin_old), (j_new, bin_new) = glb_parts(b_old), glb_parts(b_new)
    row["BIN equal"] = bin_old == bin_new
    if not row["BIN equal"]:
        out.append("the binary chunks differ")
    t = time.perf_counter()
    base = old.gltf.read_gltf(p_old, name, None)
    row["read old s"] = time.perf_counter() - t
    t = time.perf_counter()
    new = new_gltf.read_gltf(p_new, name, None)
    row["read new s"] = time.perf_counter() - t
    for label, raw in (
        ("new reader, new file", new),
        ("new reader, old file", new_gltf.read_gltf(p_old, name, None)),
        ("old reader, new file", old.gltf.read_gltf(p_new, name, None)),
    ):
        out += [f"{label}: {d}" for d in diff_raw(base, raw)]
    out += [
        f"loaded: {d}"
        for d in diff_plant(
            load_with(old.gltf.read_gltf, p_old, place=False), plant_asset.load_plant(p_new, place=False)
        )
    ]
    row["faces"] = len(mesh.faces)
    row["materials"] = len(mesh.materials)
    row["JSON keys only new"] = sorted(json_key_paths(j_new) - json_key_paths(j_old))
    return out


def json_key_paths(doc: Any, path: str = "") -> set[str]:
    """Key paths of a glTF JSON, list indices folded ("materials[].alphaMode")."""
    out = set()
    if isinstance(doc, dict):
        for k, v in doc.items():
            out.add(f"{path}.{k}" if path else k)
            out |= json_key_paths(v, f"{path}.{k}" if path else k)
    elif isinstance(doc, list):
        for v in doc:
            out |= json_key_paths(v, f"{path}[]")
    return out


def compare_scene(old: types.SimpleNamespace, species: str, scene: Any, tmp: Path, row: dict) -> list[str]:
    p_old, p_new = tmp / f"lab-{species}.old.glb", tmp / f"lab-{species}.new.glb"
    t = time.perf_counter()
    p_old.write_bytes(old.scene_glb.scene_glb_bytes(scene))
    row["write old s"] = time.perf_counter() - t
    t = time.perf_counter()
    p_new.write_bytes(scene_glb.scene_glb_bytes(scene))
    row["write new s"] = time.perf_counter() - t
    row["BIN equal"] = glb_parts(p_old.read_bytes())[1] == glb_parts(p_new.read_bytes())[1]
    t = time.perf_counter()
    base = old.scene_glb.read_scene(p_old)
    row["read old s"] = time.perf_counter() - t
    t = time.perf_counter()
    new = scene_glb.read_scene(p_new)
    row["read new s"] = time.perf_counter() - t
    out = [] if row["BIN equal"] else ["the binary chunks differ"]
    for label, sc in (
        ("new reader, new file", new),
        ("new reader, old file", scene_glb.read_scene(p_old)),
        ("old reader, new file", old.scene_glb.read_scene(p_new)),
    ):
        if [m.name for m in sc.meshes] != [m.name for m in base.meshes]:
            out.append(f"{label}: other meshes")
            continue
        for a, b in zip(base.meshes, sc.meshes, strict=True):
            out += [f"{label}: {d}" for d in diff_mesh(a.name, a, b, samples=2000)]
        for robot in base.arms:
            for (la, a), (lb, b) in zip(base.arms[robot], sc.arms[robot], strict=True):
                out += [f"{label}: {d}" for d in diff_mesh(f"{robot}/{la}", a, b, samples=0)] + (
                    [] if la == lb else [f"{label}: link {la} vs {lb}"]
                )
        if (base.labels, base.plant, list(base.arms)) != (sc.labels, sc.plant, list(sc.arms)):
            out.append(f"{label}: labels, plant or robots differ")
        if [dataclasses.astuple(x)[:2] for x in base.lights] != [dataclasses.astuple(x)[:2] for x in sc.lights]:
            out.append(f"{label}: lights differ")
    row["meshes"] = len(base.meshes) + sum(len(v) for v in base.arms.values())
    return out


def user_inputs(tmp: Path) -> list[tuple[str, Path, dict]]:
    """(name, file, load_plant keywords) of the user glTF files test_plant_files builds, good and broken."""
    import base64

    import test_plant_files as t
    import trimesh

    out: list[tuple[str, Path, dict]] = []

    def add(name: str, path: Path, **kw: Any) -> None:
        out.append((name, path, kw))

    T = trimesh.transformations.translation_matrix([0.1, 0.2, 0.3])
    add(
        "trimesh: MASK, alphaCutoff 0.3, node translation",
        t.trimesh_card_glb(
            tmp / "u1.glb", t.half_alpha(100, 0), transform=T, alphaMode="MASK", alphaCutoff=0.3, doubleSided=True
        ),
    )
    add("trimesh: the same with alpha_cutoff=0.5", tmp / "u1.glb", alpha_cutoff=0.5)
    add("trimesh: BLEND", t.trimesh_card_glb(tmp / "u2.glb", t.half_alpha(), alphaMode="BLEND"))
    rng = np.random.default_rng(5)
    add(
        "trimesh: normal and metallic-roughness maps",
        t.trimesh_card_glb(
            tmp / "u3.glb", t.half_alpha(),
            normalTexture=t.Image.fromarray(rng.integers(0, 256, (8, 8, 3), dtype=np.uint8), "RGB"),
            metallicRoughnessTexture=t.Image.fromarray(rng.integers(0, 256, (8, 8, 3), dtype=np.uint8), "RGB"),
            roughnessFactor=0.5, metallicFactor=0.25,
        ),
    )  # fmt: skip
    add(
        "trimesh: two untextured materials",
        t.two_material_glb(tmp / "u4.glb"),
        material_labels={"Leaf*": "leaf", "Bark": "stem"},
    )
    folder = tmp / "ext"
    folder.mkdir()
    for name, data in trimesh.exchange.gltf.export_gltf(trimesh.Scene(t.trimesh_card(t.half_alpha()))).items():
        (folder / name).write_bytes(data)
    add("trimesh: .gltf, external buffers", folder / "model.gltf", root=tmp)
    embedded = trimesh.exchange.gltf.export_gltf(trimesh.Scene(t.trimesh_card(t.half_alpha())), embed_buffers=True)
    (tmp / "embedded.gltf").write_bytes(embedded["model.gltf"])
    add("trimesh: .gltf, embedded buffers", tmp / "embedded.gltf")

    card = t.own_card_glb(tmp / "card.glb")
    add("agrisim card", card)
    mesh, table = t.rich_mesh()
    t.export_glb(mesh, tmp / "rich.glb", table)
    add("agrisim rich mesh: label textures, BLEND, maps, instances", tmp / "rich.glb")

    def edited(name: str, edit: Callable[[dict], None], **kw: Any) -> None:
        add(name, t.edit_glb(card, tmp / f"e{len(out)}.glb", edit), **kw)

    def mat0(d: dict) -> dict:
        return d["materials"][0]

    def base_tex(d: dict) -> dict:
        return mat0(d)["pbrMetallicRoughness"]["baseColorTexture"]

    edited(
        "KHR_texture_transform offset",
        lambda d: base_tex(d).update(extensions={"KHR_texture_transform": {"offset": [0.5, 0.0]}}),
    )
    edited(
        "KHR_texture_transform rotation, scale",
        lambda d: base_tex(d).update(extensions={"KHR_texture_transform": {"rotation": 0.3, "scale": [2.0, 0.5]}}),
    )
    dt = {"diffuseTransmissionFactor": 0.4, "diffuseTransmissionColorFactor": [0.5, 1.0, 0.2]}
    edited(
        "diffuse transmission, constant",
        lambda d: mat0(d).update(extensions={"KHR_materials_diffuse_transmission": dict(dt)}),
    )
    edited(
        "diffuse transmission, texture",
        lambda d: mat0(d).update(
            extensions={"KHR_materials_diffuse_transmission": dict(dt, diffuseTransmissionTexture={"index": 0})}
        ),
    )
    edited(
        "diffuse transmission, colour texture",
        lambda d: mat0(d).update(
            extensions={"KHR_materials_diffuse_transmission": dict(dt, diffuseTransmissionColorTexture={"index": 0})}
        ),
    )

    def spec_gloss(d: dict) -> None:
        tex = mat0(d)["pbrMetallicRoughness"].pop("baseColorTexture")
        mat0(d)["extensions"] = {
            "KHR_materials_pbrSpecularGlossiness": {"diffuseTexture": tex, "diffuseFactor": [0.9, 1.0, 0.8, 1.0]}
        }

    edited("KHR_materials_pbrSpecularGlossiness diffuse texture", spec_gloss)

    def texcoord1(d: dict) -> None:
        attrs = d["meshes"][0]["primitives"][0]["attributes"]
        attrs["TEXCOORD_1"] = attrs["TEXCOORD_0"]
        attrs["TEXCOORD_0"] = attrs["POSITION"]  # nonsense UVs on set 0: set 1 must be the one read
        base_tex(d)["texCoord"] = 1
        mat0(d)["normalTexture"] = {"index": 0, "texCoord": 1, "scale": 0.5}

    edited("TEXCOORD_1 for every texture", texcoord1)
    edited(
        "normalTexture on another UV set (refused)", lambda d: mat0(d).update(normalTexture={"index": 0, "texCoord": 1})
    )
    edited("mirrored node (scale -1)", lambda d: d["nodes"][0].update(scale=[-1, 1, 1]))
    edited(
        "rotated, scaled node",
        lambda d: d["nodes"][0].update(
            rotation=[0.1, 0.3, -0.2, 0.927362], scale=[1.5, 0.5, 2.0], translation=[0.3, -0.1, 0.7]
        ),
    )
    edited(
        "node matrix",
        lambda d: d["nodes"][0].update(matrix=[0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0.25, 0.5, -0.125, 1]),
    )
    edited(
        "parent and child nodes",
        lambda d: d.update(
            nodes=[{"children": [1], "translation": [0, 1, 0]}, {"mesh": 0, "rotation": [0, 0.70710678, 0, 0.70710678]}]
        ),
    )
    edited("triangle fan", lambda d: d["meshes"][0]["primitives"][0].update(mode=6))
    edited("triangle strip", lambda d: d["meshes"][0]["primitives"][0].update(mode=5))
    edited("no material (the default one)", lambda d: d["meshes"][0]["primitives"][0].pop("material"))

    pos = np.array([[0, 0, 0], [1, 0, 0], [9, 9, 9], [0, 1, 0]], "<f4") * 0.25
    uv = np.array([[0, 0], [255, 0], [255, 255], [0, 255]], np.uint8)
    blob = (
        pos.tobytes()
        + uv.tobytes()
        + np.array([0, 1, 3, 2], "<u2").tobytes()
        + np.array([2, 0, 0, 0], np.uint8).tobytes()
    )
    blob += np.array([0.25, 0.25, 0.0], "<f4").tobytes()
    png = io.BytesIO()
    t.Image.fromarray(t.half_alpha(), "RGBA").save(png, format="PNG")
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 8},
            {"buffer": 0, "byteOffset": 56, "byteLength": 8}, {"buffer": 0, "byteOffset": 64, "byteLength": 1},
            {"buffer": 0, "byteOffset": 68, "byteLength": 12},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "sparse": {"count": 1, "indices": {"bufferView": 3, "componentType": 5121}, "values": {"bufferView": 4}}},
            {"bufferView": 1, "componentType": 5121, "normalized": True, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 4, "type": "SCALAR"},
        ],
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode()}],
        "textures": [{"source": 0}],
        "materials": [{"name": "leaf", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "alphaMode": "MASK"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "mode": 5, "material": 0}]}],
        "nodes": [{"mesh": 0}],
    }  # fmt: skip
    (tmp / "hand.gltf").write_text(json.dumps(doc))
    add("hand-written .gltf: strip, sparse, normalized, data URIs", tmp / "hand.gltf")

    # broken files: the same message
    (tmp / "fake.glb").write_bytes(png.getvalue())
    add("broken: a PNG named .glb", tmp / "fake.glb")
    (tmp / "fake.gltf").write_text("{ not json")
    add("broken: invalid JSON", tmp / "fake.gltf")
    (tmp / "v1.gltf").write_text(json.dumps(dict(doc, asset={"version": "1.0"})))
    add("broken: glTF 1.0", tmp / "v1.gltf")
    data = bytearray(card.read_bytes())
    (tmp / "short.glb").write_bytes(bytes(data[: len(data) // 2]))
    add("broken: truncated GLB", tmp / "short.glb")
    i = data.find(b"\x89PNG")
    data[i : i + 8] = b"garbage!"
    (tmp / "badimg.glb").write_bytes(bytes(data))
    add("broken: a corrupt embedded image", tmp / "badimg.glb")
    edited("broken: lines only", lambda d: d["meshes"][0]["primitives"][0].update(mode=1))
    edited("broken: no meshes", lambda d: d.update(meshes=[], nodes=[{}]))
    edited("broken: NaN translation", lambda d: d["nodes"][0].update(translation=[0, float("nan"), 0]))
    edited("broken: Draco", lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]))
    edited("broken: no UVs", lambda d: d["meshes"][0]["primitives"][0]["attributes"].pop("TEXCOORD_0"))
    edited(
        "broken: short UVs",
        lambda d: d["accessors"][d["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"]].update(count=3),
    )
    edited("broken: a node cycle", lambda d: d["nodes"][0].update(children=[0]))
    edited("broken: index out of range", lambda d: d["meshes"][0]["primitives"][0].update(indices=0))
    ext = json.loads((folder / "model.gltf").read_text())
    ext["buffers"][0]["uri"] = "https://example.com/x.bin"
    (folder / "remote.gltf").write_text(json.dumps(ext))
    add("broken: a remote buffer", folder / "remote.gltf")
    ext["buffers"][0]["uri"] = "../../outside.bin"
    (folder / "escape.gltf").write_text(json.dumps(ext))
    add("broken: a buffer outside the root", folder / "escape.gltf", root=folder)

    def swap(d: dict) -> None:
        d["materials"][0]["extras"]["agrisim"]["label_texture"] = d["materials"][2]["pbrMetallicRoughness"][
            "baseColorTexture"
        ]["index"]

    add("broken: an RGBA label texture", t.edit_glb(tmp / "rich.glb", tmp / "swap.glb", swap))
    return out


# -- what trimesh makes of the same inputs ---------------------------------------------------------


def why_not_trimesh(tmp: Path, species_files: dict[str, Path]) -> None:
    """Figures for the claims in core/files/{gltf,gltf_materials,glb,obj}.py about trimesh."""
    import test_plant_files as t
    import trimesh

    print("\n## trimesh's glTF loader on agrisim's plant.glb (new writer)")
    for name, path in species_files.items():
        raw = new_gltf.read_gltf(path, name, None)
        doc, _ = glb_parts(path.read_bytes())
        n_prims = len(doc["meshes"][0]["primitives"])
        scene = trimesh.load_scene(path, process=False)
        geoms = list(scene.geometry.values())
        # agrisim's UVs (glTF, v down) against trimesh's flipped back: exact only where 1 - v is
        uv_ok = uv_all = 0
        colour_err = 0.0
        for g in geoms:
            mat = g.visual.material
            ours = next(m for m in raw.materials if m.name == mat.name)
            colour_err = max(
                colour_err, float(np.abs(np.asarray(mat.baseColorFactor, float) / 255.0 - np.asarray(ours.color)).max())
            )
            if getattr(g.visual, "uv", None) is not None:
                back = (1.0 - np.asarray(g.visual.uv, np.float64)[:, 1]).astype(np.float32)
                uv_all += len(back)
                uv_ok += int(np.sum(back == raw.uvs[: len(back), 1]))
        print(
            f"{name:16s} primitives {n_prims:2d} -> trimesh meshes {len(geoms):2d}; vertices {len(raw.positions)} -> "
            f"{sum(len(g.vertices) for g in geoms)}; V exact {uv_ok}/{uv_all}; largest colour error {colour_err:.4f}"
        )
    hand = tmp / "hand.gltf"
    if hand.exists():
        g = next(iter(trimesh.load_scene(hand, process=False).geometry.values()))
        print(
            f"hand.gltf: sparse vertex 2 = {g.vertices[2].tolist()} (should be [0.25, 0.25, 0.0]); normalized UV max {float(np.max(g.visual.uv)):.0f} (should be 1)"
        )
    card = tmp / "card.glb"
    fan_doc = t.edit_glb(card, tmp / "fan.glb", lambda d: d["meshes"][0]["primitives"][0].update(mode=6))
    print(f"triangle fan: trimesh meshes {len(trimesh.load_scene(fan_doc, process=False).geometry)} (agrisim: 1)")
    rng = np.random.default_rng(0)
    quats = [q / np.linalg.norm(q) for q in rng.normal(size=(1000, 4))]
    diffs = []
    for q in quats:
        ours = new_gltf._node_matrix(
            types.SimpleNamespace(matrix=None, translation=None, scale=None, rotation=q.tolist())
        )
        diffs.append(float(np.abs(ours - trimesh.transformations.quaternion_matrix(q[[3, 0, 1, 2]])).max()))
    print(
        f"1000 random unit quaternions: trimesh's rotation matrix differs from agrisim's in {sum(d > 0 for d in diffs)}, by up to {max(diffs):.2g}"
    )

    print("\n## trimesh's glTF writer on an agrisim plant")
    mesh, _ = t.rich_mesh()
    sc = trimesh.Scene()
    for i, m in enumerate(mesh.materials):
        sel = mesh.face_material == i
        pbr = trimesh.visual.material.PBRMaterial(
            name=m.name, baseColorFactor=list(m.color), alphaMode=m.alpha_mode, alphaCutoff=m.alpha_cutoff
        )
        tm = trimesh.Trimesh(
            mesh.vertices,
            mesh.faces[sel],
            process=False,
            visual=trimesh.visual.TextureVisuals(uv=mesh.uvs, material=pbr),
        )
        sc.add_geometry(tm, geom_name=m.name)
    doc = glb_parts(trimesh.exchange.gltf.export_glb(sc))[0]
    written = [m["pbrMetallicRoughness"]["baseColorFactor"] for m in doc["materials"]]
    print(
        f"{len(mesh.materials)} materials sharing {len(mesh.vertices)} vertices -> {len(doc['meshes'])} meshes with "
        f"{sum(doc['accessors'][m['primitives'][0]['attributes']['POSITION']]['count'] for m in doc['meshes'])} vertices; samplers: "
        f"{'samplers' in doc}; baseColorFactor {[round(c, 6) for c in written[0]]} for {list(mesh.materials[0].color)}"
    )

    print("\n## trimesh's OBJ loader on test_plant_files' OBJ inputs")
    opts = t.write_obj(
        tmp / "o1",
        "newmtl leaf\nKd 1 1 1\nmap_Kd -s 1 1 1 my leaf.png\nmap_d -imfchan l opacity.png\n",
        textures={"my leaf.png": np.full((8, 8, 3), 90, np.uint8), "opacity.png": t.half_alpha()[..., 3].copy()},
    )
    mat = next(iter(trimesh.load_scene(opts, process=False, group_material=False).geometry.values())).visual.material
    print(
        f"map_Kd with -s and a space in the name, map_d with -imfchan: trimesh's image {getattr(mat, 'image', None)}; agrisim: MASK with the opacity map"
    )
    ahead = tmp / "o2" / "ahead.obj"
    ahead.parent.mkdir()
    ahead.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf -3 -2 -1\nv 5 5 5\n")
    g = next(iter(trimesh.load_scene(ahead, process=False).geometry.values()))
    print(
        f"negative indices with a vertex after the face: trimesh's triangle {g.vertices[g.faces[0]].tolist()} (OBJ: the three before it)"
    )
    two = t.write_obj(
        tmp / "o3",
        "newmtl leaf\nKd 0 1 0\nnewmtl stem\nKd 0.4 0.2 0.1\n",
        obj_faces="f 1 2 3\nusemtl stem\nf 1 3 4\nusemtl leaf\nf 2 3 4\n",
    )
    geoms = trimesh.load_scene(two, process=False).geometry
    print(
        f"faces of leaf, stem, leaf in that order: trimesh's meshes {[(k, len(v.faces)) for k, v in geoms.items()]} (agrisim keeps one mesh, file order)"
    )


# ---------------------------------------------------------------------------------------------------


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", default=None, help="the commit with the hand-written code (default: see above)")
    parser.add_argument(
        "--helios", default=",".join(HELIOS_DEFAULT), help="Helios models, comma-separated, 'all' or 'none'"
    )
    parser.add_argument(
        "--why-not-trimesh", action="store_true", help="also print what trimesh's loaders and writer do"
    )
    args = parser.parse_args()
    old = load_old(args.old or default_old())
    print(f"old code: {old.rev}; new: the working tree (pygltflib {__import__('pygltflib').__version__})")
    failures: list[str] = []
    tmp = Path(tempfile.mkdtemp(prefix="agrisim-gltf-eq-"))

    def report(title: str, rows: list[dict]) -> None:
        print(f"\n## {title}")
        cols = list(dict.fromkeys(k for r in rows for k in r if k not in ("differences", "JSON keys only new")))
        print(" | ".join(cols) + " | differences")
        for r in rows:
            cells = [f"{r[c]:.3f}" if isinstance(r.get(c), float) else str(r.get(c, "")) for c in cols]
            print(" | ".join(cells) + f" | {len(r['differences'])}")
            failures.extend(f"{title} / {r[cols[0]]}: {d}" for d in r["differences"])

    from agrisim.plugins.plants.procedural import SPECIES, grow

    rows, species_files, plants = [], {}, {}
    new_keys: set[str] = set()
    for name in SPECIES:
        plant = plants[name] = grow(name, 0)
        row: dict = {"species": name}
        row["differences"] = compare_written(old, name, plant.mesh, plant.labels, tmp, row)
        new_keys |= set(row["JSON keys only new"])
        species_files[name] = tmp / "new" / f"{name}.glb"
        rows.append(row)
    report("procedural species: plant.glb (plant frame), written and read both ways", rows)
    print(f"JSON keys the new writer adds (pygltflib writes these spec defaults): {sorted(new_keys)}")

    from agrisim.config import CellConfig
    from agrisim.plugins.render.arm_visuals import arm_link_meshes
    from agrisim.plugins.rigs.paper.cell import build_cell
    from agrisim.plugins.rooms.lab.room import build_scene

    cell = build_cell(CellConfig())
    arms = {a.name: [(lm.link, lm.mesh) for lm in arm_link_meshes(a.urdf, 30000)] for a in cell.arms}
    rows = []
    for name, plant in plants.items():
        scene = dataclasses.replace(build_scene(cell, plant, labels="organs"), arms=arms)
        row = {"lab with": name}
        row["differences"] = compare_scene(old, name, scene, tmp, row)
        world = tmp / "world"
        world.mkdir(exist_ok=True)
        row["differences"] += compare_written(old, f"world-{name}", scene.mesh("plant"), scene.labels, world, {})
        rows.append(row)
    report("scene/lab.glb and scene/plant.glb (world frame) of the lab with each species", rows)

    if args.helios != "none":
        from agrisim.plugins.plants import helios

        models = helios.available_models() if args.helios == "all" else args.helios.split(",")
        rows = []
        for model in models:
            row = {"helios": model}
            t0 = time.perf_counter()
            plant = outcome(lambda m=model: helios.grow(m, 0))
            row["grow s"] = time.perf_counter() - t0
            if isinstance(plant, str):
                row["differences"] = [f"not grown: {plant}"]
            else:
                row["differences"] = compare_written(old, f"helios-{model}", plant.mesh, plant.labels, tmp, row)
            rows.append(row)
        report("Helios crops: plant.glb, written and read both ways", rows)

    rows = []
    (tmp / "user").mkdir()
    for name, path, kw in user_inputs(tmp / "user"):
        root = Path(kw["root"]).resolve() if "root" in kw else None
        a = outcome(functools.partial(load_with, old.gltf.read_gltf, path, place=False, **kw))
        b = outcome(functools.partial(plant_asset.load_plant, path, place=False, **kw))
        ra = outcome(functools.partial(old.gltf.read_gltf, path, path.name, root))
        rb = outcome(functools.partial(new_gltf.read_gltf, path, path.name, root))
        row = {"user glTF": name, "outcome": "error" if isinstance(b, str) else f"{len(b.mesh.faces)} triangles"}
        if isinstance(a, str) or isinstance(b, str):
            row["differences"] = [] if a == b else [f"{a!r} vs {b!r}"]
        else:
            row["differences"] = diff_plant(a, b) + diff_raw(ra, rb)
        rows.append(row)
    report("user glTF files (tests/unit/test_plant_files.py's inputs) through load_plant", rows)

    if args.why_not_trimesh:
        why_not_trimesh(tmp / "user", species_files)

    print(f"\n{len(failures)} differences")
    for f in failures[:50]:
        print("  " + f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
