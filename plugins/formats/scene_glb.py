"""Reads agrisim's saved scene back (``OUT/scene/lab.glb``, written by
:mod:`agrisim.plugins.sinks.dataset.scene_glb`): every mesh, the arms' link meshes, the lights, the label table
and a bench's plants (:attr:`Scene.bench`, each plant's faces of the plant mesh).

Reading gives back float32-exact vertices (the run's renderers see float64 world coordinates, but
every renderer casts them to float32 as stored here), the same texels, the same material settings.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.plugins.formats.gltf import GltfReader
from agrisim.plugins.sinks.dataset.bench import read_bench
from agrisim.plugins.sinks.dataset.scene_glb import ARM_PREFIX, FORMAT
from agrisim.scene.model import LabelTable, Light, Material, Mesh, Scene

__all__ = ["read_scene"]


def read_scene(path: Path) -> Scene:
    """The :class:`Scene` (with ``arms``) of agrisim's scene GLB at ``path``; a UserError for any
    other file."""
    shown = str(path)
    doc = GltfReader(Path(path), shown, None)
    info = doc.agrisim if isinstance(doc.agrisim, dict) else None
    if info is None or info.get("kind") != "scene":
        raise UserError(f"{shown} is not a scene saved by agrisim (no agrisim scene in its asset extras)")
    if info.get("format") != FORMAT:
        raise UserError(f"{shown}: agrisim scene format {info.get('format')!r}, this agrisim reads {FORMAT}")
    try:
        labels = LabelTable.from_json(info["labels"])
        lights = [
            Light(
                str(e["name"]),
                e["kind"],
                np.array(e["position"], np.float64),
                np.array(e["direction"], np.float64),
                tuple(float(c) for c in e["color"]),  # type: ignore[arg-type]
                float(e["intensity"]),
                float(e["radius"]),
                float(e["cone_deg"]),
            )
            for e in info["lights"]
        ]
        meshes: list[Mesh] = []
        arms: dict[str, list[tuple[str, Mesh]]] = {}
        for node in doc.plain_list("nodes"):
            mesh = _read_mesh(doc, node)
            extras = (node.get("extras") or {}).get("agrisim") or {}
            if str(node.get("name", "")).startswith(ARM_PREFIX):
                arms.setdefault(str(extras["robot"]), []).append((str(extras["link"]), mesh))
            else:
                meshes.append(mesh)
        scene = Scene(meshes, lights, labels, plant=str(info["plant"]), arms=arms)
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise UserError(f"{shown}: malformed agrisim scene ({type(exc).__name__}: {exc})") from None
    scene.bench = read_bench(info, shown)
    if scene.bench:  # the plants' faces must tile the plant mesh, as the renderers take them
        ends = [p.faces for p in scene.bench]
        n = len(scene.mesh(scene.plant).faces) if any(m.name == scene.plant for m in meshes) else -1
        if ends[0][0] != 0 or ends[-1][1] != n or any(a[1] != b[0] for a, b in zip(ends, ends[1:], strict=False)):
            raise UserError(f"{shown}: malformed agrisim scene (its bench's faces {ends} do not tile the plant's {n})")
    return scene


def _read_mesh(doc: GltfReader, node: dict[str, Any]) -> Mesh:
    """One node's mesh as written by :meth:`GlbWriter.mesh`: positions back to z up unless
    it is an arm link's (in its own frame), materials, UVs, vertex colours and leaf instances."""
    gm = doc.plain_item("meshes", node["mesh"])
    prims = gm["primitives"]
    first = prims[0]["attributes"]
    pos = doc.accessor(first["POSITION"]).astype(np.float64)
    if not str(node.get("name", "")).startswith(ARM_PREFIX):
        pos = np.column_stack([pos[:, 0], -pos[:, 2], pos[:, 1]])
    uvs = doc.accessor(first["TEXCOORD_0"]).astype(np.float32) if "TEXCOORD_0" in first else None
    colors = doc.accessor(first["COLOR_0"]).astype(np.float32) if "COLOR_0" in first else None
    materials: list[Material] = []
    index: dict[int, int] = {}
    faces, face_material, face_instance, any_instance = [], [], [], False
    for prim in prims:
        mi = int(prim["material"])
        if mi not in index:
            index[mi] = len(materials)
            materials.append(doc.material(mi)[0])
        tris = doc.accessor(prim["indices"])[:, 0].astype(np.int64).reshape(-1, 3)
        faces.append(tris)
        face_material.append(np.full(len(tris), index[mi], np.int32))
        inst = ((prim.get("extras") or {}).get("agrisim") or {}).get("face_instance")
        if inst is not None:
            face_instance.append(doc.accessor(inst)[:, 0].astype(np.uint16))
            any_instance = True
        else:
            face_instance.append(np.zeros(len(tris), np.uint16))
    return Mesh(
        str(gm.get("name") or node.get("name")),
        pos,
        np.concatenate(faces),
        materials,
        np.concatenate(face_material),
        uvs,
        np.concatenate(face_instance) if any_instance else None,
        colors,
    )
