"""One way to assemble a :class:`~agrisim.scene.model.Mesh` from pieces, for every mesh the
project builds: batches of same-shaped items (a species' thousands of leaf cards, vectorised)
and single parts with a material and a pose (the lab's walls, cabinets and pot)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from agrisim.scene.model import Material, Mesh

#: a mesh piece: (vertices V x 3, faces F x 3 indexing them, uvs V x 2)
Part = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass
class MeshBuilder:
    """Collects vertices, faces, UVs, a material index and a leaf-instance id per face, in the
    order added, into one :class:`Mesh`."""

    vertices: list[np.ndarray] = field(default_factory=list)
    faces: list[np.ndarray] = field(default_factory=list)
    uvs: list[np.ndarray] = field(default_factory=list)
    face_material: list[np.ndarray] = field(default_factory=list)
    face_instance: list[np.ndarray] = field(default_factory=list)
    #: the materials of :meth:`add_part`, in the order first seen (:meth:`build`'s default)
    materials: list[Material] = field(default_factory=list)
    next_instance: int = 1
    _n: int = 0
    _instanced: bool = False

    def add(
        self, vertices: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None, material: int, instance: object = None
    ) -> None:
        """Add a batch: ``vertices`` (N x V x 3) or (V x 3), ``faces`` (F x 3) indexing one
        item's V vertices (repeated for every item), ``material`` an index into the mesh's
        materials, ``instance`` a leaf-instance id per item or per face (None: no instances;
        a mesh without any has ``face_instance`` None)."""
        v = np.asarray(vertices, float)
        if v.ndim == 2:
            v = v[None]
        n_items, n_v = v.shape[:2]
        f = np.asarray(faces, np.int64)
        offs = (np.arange(n_items) * n_v)[:, None, None]
        ff = (f[None] + offs).reshape(-1, 3) + self._n
        self.vertices.append(v.reshape(-1, 3))
        self.faces.append(ff)
        if uvs is None:
            uvs = np.zeros((n_items * n_v, 2))
        self.uvs.append(np.asarray(uvs, float).reshape(-1, 2))
        self.face_material.append(np.full(len(ff), material, np.int32))
        if instance is not None:
            self._instanced = True
        inst = np.asarray(0 if instance is None else instance)
        if inst.ndim == 0:
            inst = np.full(n_items, int(inst))
        if inst.shape == (n_items,):
            inst = np.repeat(inst, len(f))
        self.face_instance.append(inst.astype(np.int64).reshape(-1))
        self._n += n_items * n_v

    def add_part(self, part: Part, material: Material, T: np.ndarray | None = None) -> None:
        """Add one part drawn with ``material`` (the same object shares its index), placed by
        the 4x4 pose ``T``."""
        V, F, UV = part
        if T is not None:
            V = V @ T[:3, :3].T + T[:3, 3]
        index = next((i for i, m in enumerate(self.materials) if m is material), None)
        if index is None:
            index = len(self.materials)
            self.materials.append(material)
        self.add(V, F, UV, index)

    def add_parts(self, parts: Iterable[Part], material: Material, T: np.ndarray | None = None) -> None:
        """:meth:`add_part` for each of ``parts``."""
        for p in parts:
            self.add_part(p, material, T)

    def instances(self, n: int) -> np.ndarray:
        """``n`` fresh leaf-instance ids."""
        ids = np.arange(self.next_instance, self.next_instance + n)
        self.next_instance += n
        return ids

    def transform(self, scale: float) -> None:
        """Scale everything added so far about the origin."""
        self.vertices = [v * scale for v in self.vertices]

    def bounds(self) -> tuple[float, float, float]:
        """(max radial distance from the z axis, min z, max z) of everything so far."""
        v = np.concatenate(self.vertices)
        return float(np.hypot(v[:, 0], v[:, 1]).max()), float(v[:, 2].min()), float(v[:, 2].max())

    def build(self, name: str, materials: list[Material] | None = None, *, T: np.ndarray | None = None) -> Mesh:
        """The mesh: ``materials`` (default: those of :meth:`add_part`), placed by ``T``."""
        V = np.concatenate(self.vertices)
        if T is not None:
            V = V @ T[:3, :3].T + T[:3, 3]
        instance = None
        if self._instanced:
            instance = np.concatenate(self.face_instance)
            if instance.max(initial=0) > np.iinfo(np.uint16).max:
                raise ValueError(f"{name}: more than 65535 leaf instances")
            instance = instance.astype(np.uint16)
        return Mesh(
            name,
            V,
            np.concatenate(self.faces),
            self.materials if materials is None else materials,
            np.concatenate(self.face_material),
            np.concatenate(self.uvs),
            instance,
        )
