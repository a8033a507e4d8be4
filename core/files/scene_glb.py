"""The whole rendered scene as one binary glTF (``OUT/scene/lab.glb``): written by every run that
renders, read back by ``agrisim render`` to draw the run again with another renderer.

What it holds, and how:

* every static mesh of the :class:`~agrisim.scene.model.Scene` (room, clutter, table, stands, pot,
  soil, lamp panels, the plant) as a node named after it, in world coordinates converted to
  glTF's y up ((x, y, z) -> (x, z, -y), exact in float32), with its materials as
  :mod:`agrisim.files.glb` writes them (albedo, roughness, metallic, alpha cut-outs, label
  textures and translucency in ``extras``) and its leaf instances;
* each arm link's visual mesh as a node ``arm:<robot>/<link>`` whose mesh is in the link's own
  frame, placed by the node's matrix at the pose of the first frame (so that a glTF viewer shows
  the arms where they stood); :func:`read_scene` ignores that matrix: a renderer poses the links
  per frame from ``link_poses/<frame>.json``;
* the lights, the label table and which mesh is the plant in the asset's ``extras``.

Reading gives back float32-exact vertices (the run's renderers see float64 world coordinates, but
every renderer casts them to float32 as stored here), the same texels, the same material settings.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.files.atomic import write_bytes
from agrisim.files.glb import GlbWriter
from agrisim.files.gltf import GltfReader
from agrisim.scene.model import LabelTable, Light, Material, Mesh, Scene

FORMAT = 1
ARM_PREFIX = "arm:"
#: world (z up) -> glTF (y up): (x, y, z) -> (x, z, -y)
Z_UP_TO_Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])


def scene_glb_bytes(scene: Scene, arm_poses: dict[str, dict[str, np.ndarray]] | None = None) -> bytes:
    """The bytes of ``scene`` as agrisim's scene GLB; ``arm_poses`` (robot -> link -> world_T_link)
    places the arm nodes for viewers (identity where absent)."""
    w = GlbWriter()
    nodes, meshes = [], []
    for mesh in scene.meshes:
        if len(mesh.faces) == 0:
            continue
        meshes.append(w.mesh(mesh))
        nodes.append({"name": mesh.name, "mesh": len(meshes) - 1})
    for robot, links in scene.arms.items():
        for link, mesh in links:
            meshes.append(w.mesh(mesh, z_up_to_y_up=False))
            pose = (arm_poses or {}).get(robot, {}).get(link, np.eye(4))
            matrix = Z_UP_TO_Y_UP @ np.asarray(pose, np.float64)
            node = {
                "name": f"{ARM_PREFIX}{robot}/{link}",
                "mesh": len(meshes) - 1,
                "extras": {"agrisim": {"robot": robot, "link": link}},
            }
            if not np.allclose(matrix, np.eye(4)):
                node["matrix"] = matrix.T.ravel().tolist()  # glTF matrices are column-major
            nodes.append(node)
    agrisim = {
        "format": FORMAT,
        "kind": "scene",
        "plant": scene.plant,
        "labels": scene.labels.to_json(),
        "lights": [_light_json(light) for light in scene.lights],
    }
    gltf: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "agrisim", "extras": {"agrisim": agrisim}},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
    }
    return w.finish(gltf)


def write_scene(
    path: str | os.PathLike[str], scene: Scene, arm_poses: dict[str, dict[str, np.ndarray]] | None = None
) -> None:
    """Write ``scene`` (with its arms) as agrisim's scene GLB at ``path``, atomically."""
    write_bytes(Path(path), scene_glb_bytes(scene, arm_poses))


def _light_json(light: Light) -> dict[str, Any]:
    return {
        "name": light.name,
        "kind": light.kind,
        "position": [float(x) for x in light.position],
        "direction": [float(x) for x in light.direction],
        "color": [float(c) for c in light.color],
        "intensity": float(light.intensity),
        "radius": float(light.radius),
        "cone_deg": float(light.cone_deg),
    }


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
        return Scene(meshes, lights, labels, plant=str(info["plant"]), arms=arms)
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise UserError(f"{shown}: malformed agrisim scene ({type(exc).__name__}: {exc})") from None


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
