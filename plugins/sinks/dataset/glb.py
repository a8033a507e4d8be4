"""agrisim's GLB writer: any :class:`Mesh` as a binary glTF that any viewer shows and that
:func:`agrisim.plugins.formats.plant_asset.load_plant` reads back exactly (textures, alpha settings,
label textures, the label table and leaf instances in ``extras``; the format is described in
:mod:`agrisim.plugins.formats.plant_asset`).

The document is pygltflib's object model, which it serializes into the binary glTF. What goes in
it is agrisim's: trimesh's exporter writes one vertex array per primitive (agrisim's primitives
share one, so that vertices and their order read back as they were), no samplers (label textures
need NEAREST), ``baseColorFactor`` through 8-bit colours and no ``normalTexture.scale``."""

from __future__ import annotations

import hashlib
import io
import itertools
import os
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from pygltflib import (  # type: ignore[import-untyped]  # (pygltflib ships no type hints)
    GLTF2,
    Accessor,
    Asset,
    Attributes,
    Buffer,
    BufferView,
    Node,
    NormalMaterialTexture,
    PbrMetallicRoughness,
    Primitive,
    Sampler,
    Scene,
    Texture,
    TextureInfo,
)
from pygltflib import Image as GltfImage
from pygltflib import Material as GltfMaterial
from pygltflib import Mesh as GltfMesh

from agrisim.files.atomic import write_bytes
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
        used = (
            {int(mat.label)}
            if mat.labels is None
            else set(np.flatnonzero(np.bincount(mat.labels.ravel(), minlength=256)).tolist())
        )
        if not used <= known:
            raise ValueError(
                f"material {mat.name!r} uses label ids {sorted(used - known)} missing from the label table"
            )

    w = GlbWriter()
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

#: the encoded PNGs of recent textures, by (mode, shape, SHA-1 of the texels): a run writes the
#: plant's textures twice (plant.glb, scene.glb), and successive episodes in one process (the
#: Gymnasium environment's resets, compare's and sweep's workers) share the room's; encoding
#: them is most of the scene's second. PIL encodes the same texels into the same bytes.
PNG_CACHE_BYTES = 64 << 20
_png_cache: OrderedDict[tuple[Any, ...], bytes] = OrderedDict()
_png_cache_lock = threading.Lock()
_png_cache_size = [0]  # the cached PNGs' bytes, kept as they come and go


def texture_key(pixels: np.ndarray, mode: str) -> tuple[Any, ...]:
    """What identifies a texture's PNG: its mode, shape, type and texels (SHA-1)."""
    pixels = np.ascontiguousarray(pixels)
    return (mode, pixels.shape, pixels.dtype.str, hashlib.sha1(pixels.tobytes()).hexdigest())


def texture_png(pixels: np.ndarray, mode: str, key: tuple[Any, ...] | None = None) -> bytes:
    """``pixels`` encoded as PNG in PIL's ``mode``, from the cache where it was encoded lately
    (``key``: its :func:`texture_key`, computed when not given)."""
    pixels = np.ascontiguousarray(pixels)
    key = texture_key(pixels, mode) if key is None else key
    with _png_cache_lock:
        png = _png_cache.get(key)
        if png is not None:
            _png_cache.move_to_end(key)
            return png
    buf = io.BytesIO()
    Image.fromarray(pixels, mode).save(buf, format="PNG")
    png = buf.getvalue()
    with _png_cache_lock:
        if key not in _png_cache:  # (another thread may have encoded it meanwhile)
            _png_cache[key] = png
            _png_cache_size[0] += len(png)
        while _png_cache_size[0] > PNG_CACHE_BYTES and len(_png_cache) > 1:
            _png_cache_size[0] -= len(_png_cache.popitem(last=False)[1])
    return png


class GlbWriter:
    """Collects buffer views, accessors, images, textures and materials of one binary glTF
    (:mod:`agrisim.plugins.sinks.dataset.scene_glb` writes its scenes through it too)."""

    def __init__(self) -> None:
        self.blob = bytearray()
        self.views: list[BufferView] = []
        self.accessors: list[Accessor] = []
        self.images: list[GltfImage] = []
        self.textures: list[Texture] = []
        self._image_keys: dict[tuple[Any, ...], int] = {}
        self._texture_keys: dict[tuple[int, bool], int] = {}
        self.materials: list[GltfMaterial] = []
        self._material_index: dict[int, int] = {}

    def view(self, data: bytes, target: int | None = None) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.views.append(BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(data), target=target))
        self.blob += data
        return len(self.views) - 1

    def accessor(self, arr: np.ndarray, target: int | None = None, minmax: bool = False) -> int:
        ctype = {np.dtype("<f4"): 5126, np.dtype("<u4"): 5125, np.dtype("<u2"): 5123}[arr.dtype]
        acc = Accessor(
            bufferView=self.view(np.ascontiguousarray(arr).tobytes(), target),
            componentType=ctype,
            count=int(arr.shape[0]),
            type={1: "SCALAR", 2: "VEC2", 3: "VEC3"}[arr.shape[1]],
        )
        if minmax and len(arr):
            acc.min = [float(x) for x in arr.min(axis=0)]
            acc.max = [float(x) for x in arr.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def texture(self, pixels: np.ndarray, mode: str, nearest: bool) -> int:
        pixels = np.ascontiguousarray(pixels)
        key = texture_key(pixels, mode)
        if key not in self._image_keys:
            png = texture_png(pixels, mode, key)
            self.images.append(GltfImage(bufferView=self.view(png), mimeType="image/png"))
            self._image_keys[key] = len(self.images) - 1
        tkey = (self._image_keys[key], nearest)
        if tkey not in self._texture_keys:
            self.textures.append(Texture(sampler=1 if nearest else 0, source=tkey[0]))
            self._texture_keys[tkey] = len(self.textures) - 1
        return self._texture_keys[tkey]

    def material(self, mat: Material) -> int:
        """Index of ``mat`` among the file's materials (each Material object written once):
        albedo as ``baseColorTexture``, roughness and metallic (and their texture), the normal
        texture, alpha settings, and agrisim's label, label texture, cutoff, transmittance,
        transmission texture and back side in ``extras``."""
        if id(mat) in self._material_index:
            return self._material_index[id(mat)]
        pbr = PbrMetallicRoughness(
            baseColorFactor=[float(c) for c in mat.color],
            metallicFactor=float(mat.metallic),
            roughnessFactor=float(mat.roughness),
        )
        extras: dict[str, Any] = {"label": int(mat.label), "alpha_cutoff": float(mat.alpha_cutoff)}
        if mat.transmittance is not None:
            extras["transmittance"] = [float(t) for t in mat.transmittance]
        if mat.back_color is not None:
            extras["back_color"] = [float(c) for c in mat.back_color]
        if mat.back_roughness is not None:
            extras["back_roughness"] = float(mat.back_roughness)
        if mat.albedo is not None:
            pbr.baseColorTexture = TextureInfo(index=self.texture(mat.albedo, "RGBA", nearest=False))
        if mat.labels is not None:
            extras["label_texture"] = self.texture(mat.labels, "L", nearest=True)
        if mat.transmission is not None:
            extras["transmission_texture"] = self.texture(mat.transmission, "RGB", nearest=False)
        if mat.metallic_roughness is not None:
            pbr.metallicRoughnessTexture = TextureInfo(index=self.texture(mat.metallic_roughness, "RGB", nearest=False))
        m = GltfMaterial(
            name=mat.name,
            pbrMetallicRoughness=pbr,
            alphaMode=mat.alpha_mode,
            alphaCutoff=float(mat.alpha_cutoff) if mat.alpha_mode == "MASK" else None,
            doubleSided=bool(mat.double_sided),
            extras={"agrisim": extras},
        )
        if mat.normal_map is not None:
            m.normalTexture = NormalMaterialTexture(
                index=self.texture(mat.normal_map, "RGB", nearest=False), scale=float(mat.normal_scale)
            )
        self.materials.append(m)
        self._material_index[id(mat)] = len(self.materials) - 1
        return len(self.materials) - 1

    def mesh(self, mesh: Mesh, *, z_up_to_y_up: bool = True) -> GltfMesh:
        """The glTF mesh of ``mesh`` (its materials added to the file): positions converted to
        glTF's y up ((x, y, z) -> (x, z, -y), exact in float32) unless they are in a frame of
        their own (an arm link's), one primitive per run of faces of one material, vertex
        colours as ``COLOR_0``, leaf instances in the primitives' ``extras``."""
        if z_up_to_y_up:
            v = np.column_stack([mesh.vertices[:, 0], mesh.vertices[:, 2], -mesh.vertices[:, 1]]).astype("<f4")
        else:
            v = mesh.vertices.astype("<f4")
        attributes = {"POSITION": self.accessor(v, 34962, minmax=True)}
        if mesh.uvs is not None:
            attributes["TEXCOORD_0"] = self.accessor(mesh.uvs.astype("<f4"), 34962)
        if mesh.colors is not None:
            attributes["COLOR_0"] = self.accessor(mesh.colors.astype("<f4"), 34962)
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
        for a, b in itertools.pairwise(bounds):
            prim = Primitive(
                attributes=Attributes(**attributes),
                indices=self.accessor(faces[a:b].astype("<u4").reshape(-1, 1), 34963),
                material=material_index[int(face_material[a])],
                mode=4,
            )
            if face_instance is not None:
                prim.extras = {
                    "agrisim": {"face_instance": self.accessor(face_instance[a:b].astype("<u2").reshape(-1, 1))}
                }
            primitives.append(prim)
        return GltfMesh(name=mesh.name, primitives=primitives)

    def finish(self, gltf: dict[str, Any]) -> bytes:
        """The binary glTF of ``gltf`` (its asset, scene, scenes and nodes as JSON objects, its
        meshes from :meth:`mesh`) with everything this writer collected."""
        self.blob += b"\0" * (-len(self.blob) % 4)
        doc = GLTF2(
            asset=Asset(**gltf["asset"]),
            scene=gltf.get("scene"),
            scenes=[Scene(**s) for s in gltf.get("scenes", [])],
            nodes=[Node(**n) for n in gltf["nodes"]],
            meshes=list(gltf["meshes"]),
            materials=self.materials,
            accessors=self.accessors,
            bufferViews=self.views,
            buffers=[Buffer(byteLength=len(self.blob))],
            images=self.images,
            textures=self.textures,
            samplers=[
                Sampler(wrapS=10497, wrapT=10497),
                Sampler(magFilter=9728, minFilter=9728, wrapS=10497, wrapT=10497),  # labels: nearest
            ]
            if self.images
            else [],
        )
        for where, extras in _extras(doc):
            lost = _pruned(extras)
            if lost:
                # pygltflib's JSON writer deletes None and empty lists, objects and strings at any
                # depth of extras (its delete_empty_keys); agrisim's reader needs every key back.
                raise ValueError(f"{where}: extras key {lost!r} is empty, which the glTF writer (pygltflib) would drop")
        doc.set_binary_blob(bytes(self.blob))
        return b"".join(doc.save_to_bytes())


def _extras(doc: GLTF2) -> list[tuple[str, Any]]:
    """(where, extras) of every part of ``doc`` agrisim writes extras into."""
    parts = [("asset", doc.asset.extras)]
    parts += [(f"node {n.name!r}", n.extras) for n in doc.nodes]
    parts += [(f"material {m.name!r}", m.extras) for m in doc.materials]
    parts += [(f"mesh {m.name!r}", p.extras) for m in doc.meshes for p in m.primitives]
    return parts


def _pruned(value: Any, path: str = "") -> str | None:
    """The first key under ``value`` that pygltflib's JSON writer would delete, or None."""
    if isinstance(value, dict):
        for k, v in value.items():
            here = f"{path}.{k}" if path else str(k)
            if v is None or (hasattr(v, "__len__") and len(v) == 0):
                return here
            found = _pruned(v, here)
            if found:
                return found
    elif isinstance(value, list):
        for i, v in enumerate(value):
            found = _pruned(v, f"{path}[{i}]") if isinstance(v, dict) else None
            if found:
                return found
    return None
