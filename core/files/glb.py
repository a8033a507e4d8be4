"""agrisim's GLB writer: any :class:`Mesh` as a binary glTF that any viewer shows and that
:func:`agrisim.files.plant_asset.load_plant` reads back exactly (textures, alpha settings,
label textures, the label table and leaf instances in ``extras``; the format is described in
:mod:`agrisim.files.plant_asset`)."""

from __future__ import annotations

import hashlib
import io
import json
import os
import struct
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from agrisim.files.atomic import write_bytes
from agrisim.files.gltf import CHUNK_BIN, CHUNK_JSON, GLB_MAGIC
from agrisim.scene.model import LabelTable, Material, Mesh


def export_glb(mesh: Mesh, path: str | os.PathLike[str], labels: LabelTable) -> None:
    """Write ``mesh`` (z-up, world or plant frame) as a binary glTF at ``path``, atomically.

    Each material's albedo (with alpha) is its ``baseColorTexture``; ``alphaMode``,
    ``alphaCutoff`` and ``doubleSided`` are the material's; its label texture and constant label
    are in the material's ``extras``; the label table in the asset's ``extras`` (module doc).
    """
    write_bytes(Path(path), glb_bytes(mesh, labels))


def glb_bytes(mesh: Mesh, labels: LabelTable) -> bytes:
    """The bytes :func:`export_glb` writes."""
    if len(mesh.faces) == 0:
        raise ValueError(f"mesh {mesh.name!r} has no triangles to export")
    known = {lab.id for lab in labels.labels}
    for mat in mesh.materials:
        used = {int(mat.label)} if mat.labels is None else set(np.flatnonzero(np.bincount(mat.labels.ravel(), minlength=256)).tolist())
        if not used <= known:
            raise ValueError(f"material {mat.name!r} uses label ids {sorted(used - known)} missing from the label table")

    w = _GlbWriter()
    gltf_mesh = w.mesh(mesh)
    gltf: dict[str, Any] = {
        "asset": {
            "version": "2.0",
            "generator": "agrisim",
            "extras": {
                "agrisim": {
                    "format": 1,
                    "labels": labels.to_json(),
                }
            },
        },
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": mesh.name, "mesh": 0}],
        "meshes": [gltf_mesh],
    }
    return w.finish(gltf)


# --------------------------------------------------------------------------------------------


class _GlbWriter:
    """Collects buffer views, accessors, images and textures of one binary glTF."""

    def __init__(self) -> None:
        self.blob = bytearray()
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []
        self.images: list[dict[str, Any]] = []
        self.textures: list[dict[str, Any]] = []
        self._image_keys: dict[tuple[Any, ...], int] = {}
        self._texture_keys: dict[tuple[int, bool], int] = {}
        self.materials: list[dict[str, Any]] = []
        self._material_index: dict[int, int] = {}

    def view(self, data: bytes, target: int | None = None) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        v: dict[str, Any] = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if target is not None:
            v["target"] = target
        self.blob += data
        self.views.append(v)
        return len(self.views) - 1

    def accessor(self, arr: np.ndarray, target: int | None = None, minmax: bool = False) -> int:
        ctype = {np.dtype("<f4"): 5126, np.dtype("<u4"): 5125, np.dtype("<u2"): 5123}[arr.dtype]
        acc: dict[str, Any] = {
            "bufferView": self.view(np.ascontiguousarray(arr).tobytes(), target),
            "componentType": ctype,
            "count": int(arr.shape[0]),
            "type": {1: "SCALAR", 2: "VEC2", 3: "VEC3"}[arr.shape[1]],
        }
        if minmax and len(arr):
            acc["min"] = [float(x) for x in arr.min(axis=0)]
            acc["max"] = [float(x) for x in arr.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def texture(self, pixels: np.ndarray, mode: str, nearest: bool) -> int:
        key = (mode, pixels.shape, hashlib.sha1(np.ascontiguousarray(pixels).tobytes()).hexdigest())
        if key not in self._image_keys:
            buf = io.BytesIO()
            Image.fromarray(np.ascontiguousarray(pixels), mode).save(buf, format="PNG")
            self.images.append({"bufferView": self.view(buf.getvalue()), "mimeType": "image/png"})
            self._image_keys[key] = len(self.images) - 1
        tkey = (self._image_keys[key], nearest)
        if tkey not in self._texture_keys:
            self.textures.append({"sampler": 1 if nearest else 0, "source": tkey[0]})
            self._texture_keys[tkey] = len(self.textures) - 1
        return self._texture_keys[tkey]

    def material(self, mat: Material) -> int:
        """Index of ``mat`` among the file's materials (each Material object written once):
        albedo as ``baseColorTexture``, roughness and metallic (and their texture), the normal
        texture, alpha settings, and agrisim's label, label texture, cutoff, transmittance and
        transmission texture in ``extras``."""
        if id(mat) in self._material_index:
            return self._material_index[id(mat)]
        pbr: dict[str, Any] = {
            "baseColorFactor": [float(c) for c in mat.color],
            "metallicFactor": float(mat.metallic),
            "roughnessFactor": float(mat.roughness),
        }
        extras: dict[str, Any] = {"label": int(mat.label), "alpha_cutoff": float(mat.alpha_cutoff)}
        if mat.transmittance is not None:
            extras["transmittance"] = [float(t) for t in mat.transmittance]
        if mat.albedo is not None:
            pbr["baseColorTexture"] = {"index": self.texture(mat.albedo, "RGBA", nearest=False)}
        if mat.labels is not None:
            extras["label_texture"] = self.texture(mat.labels, "L", nearest=True)
        if mat.transmission is not None:
            extras["transmission_texture"] = self.texture(mat.transmission, "RGB", nearest=False)
        if mat.metallic_roughness is not None:
            pbr["metallicRoughnessTexture"] = {"index": self.texture(mat.metallic_roughness, "RGB", nearest=False)}
        m: dict[str, Any] = {
            "name": mat.name,
            "pbrMetallicRoughness": pbr,
            "alphaMode": mat.alpha_mode,
            "doubleSided": bool(mat.double_sided),
            "extras": {"agrisim": extras},
        }
        if mat.alpha_mode == "MASK":
            m["alphaCutoff"] = float(mat.alpha_cutoff)
        if mat.normal_map is not None:
            m["normalTexture"] = {"index": self.texture(mat.normal_map, "RGB", nearest=False), "scale": float(mat.normal_scale)}
        self.materials.append(m)
        self._material_index[id(mat)] = len(self.materials) - 1
        return len(self.materials) - 1

    def mesh(self, mesh: Mesh, *, z_up_to_y_up: bool = True) -> dict[str, Any]:
        """The glTF mesh of ``mesh`` (its materials added to the file): positions converted to
        glTF's y up ((x, y, z) -> (x, z, -y), exact in float32) unless they are in a frame of
        their own (an arm link's), one primitive per run of faces of one material, leaf
        instances in the primitives' ``extras``."""
        if z_up_to_y_up:
            v = np.column_stack([mesh.vertices[:, 0], mesh.vertices[:, 2], -mesh.vertices[:, 1]]).astype("<f4")
        else:
            v = mesh.vertices.astype("<f4")
        attributes = {"POSITION": self.accessor(v, 34962, minmax=True)}
        if mesh.uvs is not None:
            attributes["TEXCOORD_0"] = self.accessor(mesh.uvs.astype("<f4"), 34962)
        material_index = [self.material(m) for m in mesh.materials]
        faces, face_material, face_instance = mesh.faces, mesh.face_material, mesh.face_instance
        starts = np.flatnonzero(np.diff(face_material)) + 1
        if len(starts) + 1 > 4 * len(mesh.materials) + 16:  # interleaved: group by material instead
            order = np.argsort(face_material, kind="stable")
            faces, face_material = faces[order], face_material[order]
            face_instance = None if face_instance is None else face_instance[order]
            starts = np.flatnonzero(np.diff(face_material)) + 1
        bounds = [0, *starts.tolist(), len(faces)]
        primitives = []
        for a, b in zip(bounds[:-1], bounds[1:]):
            prim: dict[str, Any] = {
                "attributes": dict(attributes),
                "indices": self.accessor(faces[a:b].astype("<u4").reshape(-1, 1), 34963),
                "material": material_index[int(face_material[a])],
                "mode": 4,
            }
            if face_instance is not None:
                prim["extras"] = {"agrisim": {"face_instance": self.accessor(face_instance[a:b].astype("<u2").reshape(-1, 1))}}
            primitives.append(prim)
        return {"name": mesh.name, "primitives": primitives}

    def finish(self, gltf: dict[str, Any]) -> bytes:
        if self.materials:
            gltf["materials"] = self.materials
        self.blob += b"\0" * (-len(self.blob) % 4)
        gltf["buffers"] = [{"byteLength": len(self.blob)}]
        gltf["bufferViews"] = self.views
        gltf["accessors"] = self.accessors
        if self.images:
            gltf["images"] = self.images
            gltf["textures"] = self.textures
            gltf["samplers"] = [
                {"wrapS": 10497, "wrapT": 10497},
                {"magFilter": 9728, "minFilter": 9728, "wrapS": 10497, "wrapT": 10497},  # labels: nearest
            ]
        doc = json.dumps(gltf, separators=(",", ":"), allow_nan=False).encode()
        doc += b" " * (-len(doc) % 4)
        total = 12 + 8 + len(doc) + 8 + len(self.blob)
        return b"".join(
            [
                struct.pack("<4sII", GLB_MAGIC, 2, total),
                struct.pack("<II", len(doc), CHUNK_JSON),
                doc,
                struct.pack("<II", len(self.blob), CHUNK_BIN),
                bytes(self.blob),
            ]
        )
