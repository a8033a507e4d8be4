"""The glTF 2.0 reader (``.gltf`` with external or embedded buffers, and ``.glb``): the scene's
nodes and triangle primitives, with their transforms, materials and agrisim's own ``extras``,
into one :class:`RawMesh`. :mod:`agrisim.plugins.formats.plant_asset` documents what is honoured.

The document comes from :mod:`agrisim.plugins.formats.gltf_document` (pygltflib), the materials from
:mod:`agrisim.plugins.formats.gltf_materials`. The walk over the nodes is agrisim's: it keeps every
primitive's vertices and triangles in file order (one vertex array per shared accessor, as
agrisim's writer shares one among a mesh's primitives), bit for bit, reads triangle fans and
refuses node cycles, where trimesh's reader gives each primitive its own copy of a shared vertex
array, flips V in float32 (not exactly invertible), skips fans and silently drops the edge that
closes a cycle."""

from __future__ import annotations

import math
import struct
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.plugins.formats.asset_reading import RawMesh
from agrisim.plugins.formats.gltf_document import GltfDocument, get
from agrisim.plugins.formats.gltf_materials import ReadMaterial, default_material, read_material
from agrisim.scene.model import LabelTable, Material

__all__ = ["read_gltf"]


class GltfReader(GltfDocument):
    """A glTF document read into agrisim's mesh (:mod:`agrisim.plugins.sinks.dataset.scene_glb` reads its
    scenes through it too)."""

    def __init__(self, path: Path, shown: str, root: Path | None) -> None:
        super().__init__(path, shown, root)
        self._materials: dict[int | None, ReadMaterial] = {}

    def material(self, index: int | None) -> ReadMaterial:
        """(material, TEXCOORD set of its textures, KHR_texture_transform or None, texture name)
        of material ``index`` (None: the spec's default material)."""
        if index not in self._materials:
            self._materials[index] = default_material() if index is None else read_material(self, index)
        return self._materials[index]

    def read(self) -> RawMesh:
        """The whole default scene as one mesh."""
        try:
            return self._read()
        except (KeyError, IndexError, TypeError, ValueError, AttributeError, struct.error) as e:
            if isinstance(e, UserError):
                raise
            raise self.error(f"malformed glTF ({type(e).__name__}: {e})") from None

    def _roots(self) -> list[int]:
        scenes = self.items("scenes")
        if scenes:
            scene = self.item("scenes", 0 if self.gltf.scene is None else self.gltf.scene)
            return list(scene.nodes or [])
        nodes = self.items("nodes")
        children = {c for n in nodes for c in n.children or []}
        return [i for i in range(len(nodes)) if i not in children]

    # One pass over the document's nodes and primitives; accessors and images are helpers.
    def _read(self) -> RawMesh:
        n_materials = len(self.items("materials"))
        positions: list[np.ndarray] = []
        uvs: list[np.ndarray] = []
        has_uv: list[np.ndarray] = []
        colors: list[np.ndarray] = []
        faces: list[np.ndarray] = []
        face_mat: list[np.ndarray] = []
        face_inst: list[np.ndarray] = []
        any_instance = False
        seen: dict[tuple[Any, ...], int] = {}
        count = 0
        visit = 0
        used_default = False
        stack: list[tuple[int, np.ndarray, int]] = [(r, np.eye(4), 0) for r in reversed(self._roots())]
        if not self.items("meshes"):
            raise self.error("not a mesh: the file has no meshes")
        while stack:
            node_i, parent_T, depth = stack.pop()
            if depth > 256:
                raise self.error("the node hierarchy has a cycle")
            node = self.item("nodes", node_i)
            T = parent_T @ _node_matrix(node)
            for child in reversed(node.children or []):
                stack.append((child, T, depth + 1))
            if node.mesh is None:
                continue
            visit += 1
            identity = np.array_equal(T, np.eye(4))
            flip = np.linalg.det(T[:3, :3]) < 0
            mesh = self.item("meshes", node.mesh)
            mname = mesh.name or f"mesh {node.mesh}"
            for pi, prim in enumerate(mesh.primitives or []):
                attrs = prim.attributes
                position = get(attrs, "POSITION")
                mode = prim.mode
                if position is None or mode not in (4, 5, 6):
                    continue  # points and lines have no surface
                mat_i = prim.material
                mat, texcoord, transform, tex_name = self.material(mat_i)
                if mat_i is None:
                    used_default = True
                pos = self.accessor(position)
                if pos.shape[1] != 3:
                    raise self.error(f"{mname} primitive {pi}: POSITION is not a VEC3 accessor")
                n = len(pos)
                where = f"{mname} primitive {pi} (material '{mat.name}')"
                uv_key = f"TEXCOORD_{texcoord}"
                uv_acc = get(attrs, uv_key)
                textured = mat.albedo is not None or mat.labels is not None
                uv = None
                if uv_acc is not None:
                    uv = self.accessor(uv_acc)
                    if uv.shape[1] != 2:
                        raise self.error(f"{where}: {uv_key} is not a VEC2 accessor")
                    if len(uv) != n:
                        raise self.error(f"{where}: {uv_key} has {len(uv)} UVs for {n} vertices")
                elif textured:
                    raise self.error(f"{where} uses texture '{tex_name}' but has no UVs ({uv_key})")
                color_acc = get(attrs, "COLOR_0")
                color = None
                if color_acc is not None:
                    color = self.accessor(color_acc)
                    if color.shape[1] not in (3, 4) or len(color) != n:
                        raise self.error(f"{where}: COLOR_0 is not a VEC3 or VEC4 accessor of {n} colours")
                    # glTF's vertex colours are linear, within 0..1 (alpha is not a colour: dropped)
                    color = np.clip(color[:, :3], 0.0, 1.0).astype(np.float32)
                key = (visit, position, uv_acc, transform, color_acc)
                if key in seen:
                    base = seen[key]
                else:
                    p = pos.astype(np.float64)
                    if not identity:
                        p = p @ T[:3, :3].T + T[:3, 3]
                    positions.append(p)
                    if uv is not None:
                        uv32 = _uv_transform(uv, transform).astype(np.float32)
                        uvs.append(uv32)
                        has_uv.append(np.ones(n, bool))
                    else:
                        uvs.append(np.zeros((n, 2), np.float32))
                        has_uv.append(np.zeros(n, bool))
                    colors.append(np.ones((n, 3), np.float32) if color is None else color)
                    base = seen[key] = count
                    count += n
                if prim.indices is not None:
                    idx = self.accessor(prim.indices)
                    if idx.shape[1] != 1 or idx.dtype.kind not in "iu":
                        raise self.error(f"{where}: indices are not an integer SCALAR accessor")
                    idx = idx[:, 0].astype(np.int64)
                else:
                    idx = np.arange(n, dtype=np.int64)
                if len(idx) and (idx.min() < 0 or idx.max() >= n):
                    raise self.error(f"{where}: index {int(idx.max())} is out of range for {n} vertices")
                tris = _triangles(idx, mode)
                if flip:
                    tris = tris[:, [0, 2, 1]]
                faces.append(tris + base)
                face_mat.append(np.full(len(tris), n_materials if mat_i is None else mat_i, np.int64))
                inst = np.zeros(len(tris), np.uint16)
                inst_acc = get(prim.extras, "agrisim", "face_instance") if self.agrisim is not None else None
                if inst_acc is not None:
                    a = self.accessor(inst_acc)
                    if a.shape != (len(tris), 1):
                        raise self.error(f"{where}: face_instance has {len(a)} entries for {len(tris)} triangles")
                    inst, any_instance = a[:, 0].astype(np.uint16), True
                face_inst.append(inst)

        if not faces or sum(len(f) for f in faces) == 0:
            raise self.error("no triangles: the scene has no triangle meshes")
        materials = [self.material(i)[0] for i in range(n_materials)]
        names = [self.material(i)[3] for i in range(n_materials)]
        if used_default:
            materials.append(self.material(None)[0])
            names.append(None)
        any_uv = any(h.any() for h in has_uv)
        any_color = any(not np.all(c == 1.0) for c in colors)
        raw = RawMesh(
            positions=np.concatenate(positions),
            faces=np.concatenate(faces),
            face_material=np.concatenate(face_mat),
            materials=materials,
            uvs=np.concatenate(uvs) if any_uv else None,
            has_uv=np.concatenate(has_uv),
            texture_names=names,
            face_instance=np.concatenate(face_inst) if any_instance else None,
            colors=np.concatenate(colors) if any_color else None,
        )
        if self.agrisim is not None:
            raw.labels = self._label_table(materials)
        return raw

    def _label_table(self, materials: list[Material]) -> LabelTable | None:
        entries = self.agrisim.get("labels") if isinstance(self.agrisim, dict) else None
        if entries is None:
            return None
        try:
            table = LabelTable.from_json(entries)
        except (KeyError, TypeError, ValueError) as e:
            raise self.error(f"malformed agrisim label table ({e})") from None
        known = {lab.id for lab in table.labels}
        for mat in materials:
            used = (
                {mat.label}
                if mat.labels is None
                else set(np.flatnonzero(np.bincount(mat.labels.ravel(), minlength=256)).tolist())
            )
            if not used <= known:
                raise self.error(
                    f"material '{mat.name}' uses label ids {sorted(used - known)}, which the file's label table does not list"
                )
        return table


# By hand: pygltflib keeps a node's transform as numbers, and trimesh's quaternion_matrix (it
# normalises, then takes an outer product) differs from this one by up to 1e-15 on unit quaternions,
# moving the vertices of rotated nodes by an ulp from what agrisim has always read.
def _node_matrix(node: Any) -> np.ndarray:
    if node.matrix is not None:
        m = np.asarray(node.matrix, dtype=np.float64)
        if m.shape != (16,):
            raise ValueError(f"node matrix must have 16 numbers, got {m.shape}")
        return m.reshape(4, 4).T  # column-major
    T = np.eye(4)
    t = [0.0, 0.0, 0.0] if node.translation is None else node.translation
    x, y, z, w = [0.0, 0.0, 0.0, 1.0] if node.rotation is None else node.rotation
    s = [1.0, 1.0, 1.0] if node.scale is None else node.scale
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    T[:3, :3] = R * np.asarray(s, dtype=np.float64)[None, :]
    T[:3, 3] = t
    return T


def _triangles(idx: np.ndarray, mode: int) -> np.ndarray:
    if mode == 4:
        return idx[: len(idx) // 3 * 3].reshape(-1, 3)
    if len(idx) < 3:
        return np.zeros((0, 3), np.int64)
    k = np.arange(len(idx) - 2)
    if mode == 5:  # strip: every other triangle swaps its first two corners to keep the winding
        even = k % 2 == 0
        a = np.where(even, idx[k], idx[k + 1])
        b = np.where(even, idx[k + 1], idx[k])
        return np.column_stack([a, b, idx[k + 2]])
    return np.column_stack([np.full(len(k), idx[0]), idx[k + 1], idx[k + 2]])  # fan


def _uv_transform(uv: np.ndarray, t: tuple[float, ...] | None) -> np.ndarray:
    """KHR_texture_transform (offset, rotation, scale) applied to glTF UVs."""
    if t is None:
        return uv
    ox, oy, rot, sx, sy = t
    u, v = uv[:, 0].astype(np.float64) * sx, uv[:, 1].astype(np.float64) * sy
    c, s = math.cos(rot), math.sin(rot)
    return np.column_stack([c * u + s * v + ox, -s * u + c * v + oy])


def read_gltf(path: Path, shown: str, root: Path | None) -> RawMesh:
    """Read the glTF file at ``path`` (``shown`` names it in errors; ``root`` confines the files it refers to)."""
    return GltfReader(path, shown, root).read()
