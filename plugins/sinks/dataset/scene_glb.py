"""The whole rendered scene as one binary glTF (``OUT/scene/lab.glb``): written by every run that
renders, read back (:mod:`agrisim.plugins.formats.scene_glb`) by ``agrisim render`` to draw the
run again with another renderer.

What it holds, and how:

* every static mesh of the :class:`~agrisim.scene.model.Scene` (room, clutter, table, stands, pot,
  soil, lamp panels, the plant) as a node named after it, in world coordinates converted to
  glTF's y up ((x, y, z) -> (x, z, -y), exact in float32), with its materials as
  :mod:`agrisim.plugins.sinks.dataset.glb` writes them (albedo, roughness, metallic, alpha cut-outs, label
  textures and translucency in ``extras``) and its leaf instances;
* each arm link's visual mesh as a node ``arm:<robot>/<link>`` whose mesh is in the link's own
  frame, placed by the node's matrix at the pose of the first frame (so that a glTF viewer shows
  the arms where they stood); the reader ignores that matrix: a renderer poses the links
  per frame from ``link_poses/<frame>.json``;
* the lights, the label table and which mesh is the plant in the asset's ``extras``, and a
  bench's plants (:mod:`agrisim.plugins.sinks.dataset.bench`, with each plant's range of the
  plant mesh's faces: the writer keeps each plant's faces together, in the order of its materials).

Reading gives back float32-exact vertices (the run's renderers see float64 world coordinates, but
every renderer casts them to float32 as stored here), the same texels, the same material settings.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.files.atomic import write_bytes
from agrisim.plugins.sinks.dataset import bench
from agrisim.plugins.sinks.dataset.glb import GlbWriter
from agrisim.scene.model import Light, Scene

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
    if scene.bench:  # each plant's faces of the plant mesh (a run of one plant writes no key)
        agrisim[bench.KEY] = bench.bench_rows(scene.bench, faces=True)
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
