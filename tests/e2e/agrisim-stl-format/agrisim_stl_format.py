"""STL plants (``--plant scan.stl``): triangles only, read by trimesh, z up unless ``[plant_file]
up = "y"``, scaled, placed in the plant frame, one green double-sided material, label 1 "plant",
each connected piece of surface a leaf instance."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from agrisim import BackendSpec, hookimpl
from agrisim.errors import UserError
from agrisim.interfaces import PlantReader
from agrisim.scene.model import Label, LabelTable, Material, Mesh, Plant

GREEN = Material("leaf", color=(0.1, 0.35, 0.05, 1.0), double_sided=True, label=1)
TABLE = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "plant", (0, 255, 0))])


class StlFormat(PlantReader):
    suffixes = (".stl",)

    def __init__(self, options: Any) -> None:
        self.options = options

    def read(self, path: Path, settings: Any, *, place: bool = True) -> Plant:
        try:
            mesh = trimesh.load(path, file_type="stl", force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a bad file
            raise UserError(f"{path.name}: not an STL file trimesh can read ({type(exc).__name__})") from None
        if not isinstance(mesh, trimesh.Trimesh) or not len(mesh.faces):
            raise UserError(f"{path.name}: the STL holds no triangles")
        mesh.merge_vertices()  # STL repeats each vertex in every triangle: one per position
        v = np.asarray(mesh.vertices, float)
        if settings.up == "y":
            v = np.column_stack([v[:, 0], -v[:, 2], v[:, 1]])
        v = v * settings.scale
        if place:
            lo, hi = v.min(axis=0), v.max(axis=0)
            v = v - np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
        faces = np.asarray(mesh.faces)
        pieces = trimesh.graph.connected_component_labels(mesh.face_adjacency, node_count=len(faces))
        drawn = Mesh(path.stem, v, faces, [GREEN], np.zeros(len(faces), np.int32), None, (pieces + 1).astype(np.uint16))
        return Plant(path.stem, drawn, TABLE)


@hookimpl
def agrisim_plant_formats() -> list[BackendSpec]:
    return [BackendSpec(name="stl", factory=StlFormat, description="STL meshes (a scanner's or a CAD tool's)")]
