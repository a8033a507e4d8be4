"""User plant assets in, ground-truth plants out.

:func:`load_plant` reads a plant asset (glTF 2.0 ``.gltf``/``.glb``, or ``.obj`` with its ``.mtl``
and texture images) into an :class:`agrisim.scene.Plant`; :func:`export_glb` writes any
:class:`agrisim.scene.Mesh` as a binary glTF that carries everything agrisim needs to read it back
exactly (albedo with alpha and alpha settings, the label texture, the label table).

Frames
------
* glTF is y-up (spec); agrisim is z-up. Reading maps a point ``(x, y, z)`` of the asset to
  ``(x, -z, y)`` (a +90 deg rotation about x, as Blender's importer does); :func:`export_glb` maps
  ``(x, y, z)`` to ``(x, z, -y)``. Both are exact (only sign flips and swaps).
* OBJ has no up axis; most exporters (Blender, Maya, Quixel) write y-up, so OBJ is read as y-up
  too. ``up="z"`` reads either format as z-up (no rotation).
* Node transforms of glTF scene graphs are applied (a transform with negative determinant
  flips the triangles' winding, as the spec says), so the result is one mesh in the asset's frame.
* Then, unless ``place=False``, the plant is moved into the *plant frame*: lowest point at
  z = 0, the bounding box centred on x = y = 0 (origin at the centre of the soil surface).

Materials and opacity
---------------------
* glTF: ``baseColorTexture`` (RGBA) and ``baseColorFactor``, ``alphaMode`` OPAQUE/MASK/BLEND,
  ``alphaCutoff`` (default 0.5) and ``doubleSided`` (default false) are honoured as written;
  ``KHR_texture_transform`` on the base colour texture is baked into the UVs;
  ``KHR_materials_pbrSpecularGlossiness`` diffuse textures are read when there is no base colour.
  Draco/meshopt-compressed or basisu-textured files are refused with a clear message.
* OBJ + MTL: ``map_Kd`` is the albedo (``Kd`` is its colour when there is none; with a texture,
  ``Kd`` is ignored, as Blender does); a ``map_Kd`` image whose alpha is not all opaque cuts the
  card: alpha mode MASK, cutoff 0.5. ``map_d`` gives the opacity (the image's alpha channel if it
  has one, else its luminance; ``-imfchan`` is honoured) and also means MASK. ``d`` < 1 sets the
  colour's alpha and BLEND. ``Tr`` is ignored (exporters disagree on its sign). ``-o``/``-s``
  texture options are baked into the UVs. OBJ materials are double-sided (leaf cards are).
* ``alpha_cutoff=`` overrides the cutoff of every MASK/BLEND material.

Labels (first that applies)
---------------------------
1. ``label_texture=PNG``: a texture at the albedo's UVs (and of the albedo's size). Either label
   ids (8-bit grey, 16-bit grey < 256, or a palette image whose indices are the ids, as PASCAL
   VOC masks) named by ``label_names={id: name}``, or flat label *colours*, as the paper's GIMP
   textures (black = background; each other colour one label, named ``label_names["#rrggbb"]``
   or after the paper's colours: green leaf, blue flower_white, red flower_purple).
2. ``material_labels={"Leaf*": "leaf", "Bark": "stem", "Pot": "background"}``: material-name
   patterns (``fnmatch``, first match wins) to organ names; organs get ids 1, 2, ... in the order
   they first appear among the values; "background" is id 0. Every material must match a pattern
   and every pattern a material.
3. An agrisim GLB's own label textures / constant labels and label table (see :func:`export_glb`).
4. Otherwise every triangle is label 1, "plant".

agrisim's GLB
-------------
Standard glTF 2.0 (any viewer shows it), plus ``extras``:
``asset.extras.agrisim = {"format": 1, "labels": [{"id", "name", "color"}, ...]}``; per material
``extras.agrisim = {"label": <constant id>, "label_texture": <texture index>, "alpha_cutoff": c}``
(the label texture is an 8-bit grey PNG of ids with a NEAREST sampler); per primitive
``extras.agrisim = {"face_instance": <accessor of uint16 per triangle>}`` when the mesh has leaf
instances. One primitive per run of consecutive triangles with the same material, all sharing one
vertex array, so vertices, triangles (and their order), UVs, textures, alpha settings and labels
read back identical (positions are float32 in glTF: exact for float32 vertices, <= 0.1 um off at
1 m otherwise). Only when materials alternate in many short runs are triangles grouped by material.
"""

from __future__ import annotations

import base64
import dataclasses
import fnmatch
import hashlib
import io
import json
import math
import os
import re
import struct
import urllib.parse
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from PIL import Image, UnidentifiedImageError

from agrisim.atomic import write_bytes
from agrisim.errors import UserError
from agrisim.scene import Label, LabelTable, Material, Mesh, Plant

__all__ = ["AssetError", "FORMATS", "MAX_SIZE", "export_glb", "glb_bytes", "load_plant"]

FORMATS = (".glb", ".gltf", ".obj")
"""File suffixes :func:`load_plant` reads."""

MAX_SIZE = 3.0
"""Largest sane plant, m (longest side of its bounding box)."""

#: Label colours of the paper (Fig. 3): leaves green, white flowers blue, purple flowers red,
#: stems deep purple.
ORGAN_COLORS: dict[str, tuple[int, int, int]] = {
    "plant": (0, 255, 0),
    "leaf": (0, 255, 0),
    "flower_white": (0, 0, 255),
    "flower_purple": (255, 0, 0),
    "stem": (96, 0, 128),
}
_MORE_COLORS = [
    (255, 255, 0), (0, 255, 255), (255, 0, 255), (255, 128, 0), (128, 255, 0), (0, 128, 255),
    (255, 0, 128), (128, 128, 255), (255, 128, 128), (128, 255, 128), (160, 82, 45), (255, 255, 255),
]  # fmt: skip

_MAX_LABEL_COLOURS = 64


class AssetError(UserError):
    """A plant asset cannot be read: the message names the file and the problem."""


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------


def load_plant(
    path: str | os.PathLike[str],
    *,
    label_texture: str | os.PathLike[str] | None = None,
    label_names: Mapping[int | str, str] | None = None,
    material_labels: Mapping[str, str] | None = None,
    alpha_cutoff: float | None = None,
    name: str | None = None,
    up: Literal["y", "z"] | None = None,
    scale: float = 1.0,
    place: bool = True,
    max_size: float = MAX_SIZE,
    root: str | os.PathLike[str] | None = None,
) -> Plant:
    """Read a plant asset (``.glb``, ``.gltf``, ``.obj`` + ``.mtl``) as a :class:`Plant`.

    Args:
        path: the asset. With ``root``, a relative path is taken inside ``root``.
        label_texture: a PNG of label ids or label colours at the albedo's UVs (module doc).
        label_names: names of the label texture's ids (``{2: "stem"}``) or colours
            (``{"#00ff00": "leaf"}``).
        material_labels: material-name pattern -> organ name (module doc).
        alpha_cutoff: cutoff of every MASK/BLEND material instead of the file's.
        name: the plant's name (default: the file's stem).
        up: the asset's up axis, ``"y"`` (default for glTF, by its spec, and for OBJ) or ``"z"``.
        scale: multiplies the coordinates (``0.01`` for an asset in centimetres).
        place: move into the plant frame (lowest point at z = 0, centred in x/y).
        max_size: refuse a plant whose bounding box is longer than this, m.
        root: if given, the asset and every file it refers to must lie inside this directory
            (``..`` and symlinks out of it are refused).

    Raises:
        AssetError: (a :class:`UserError`) naming the file and the problem.
    """
    shown = str(path)
    root_dir = _root_dir(root)
    real = _locate(Path(path), root_dir, shown, base=root_dir)
    suffix = Path(path).suffix.lower() or real.suffix.lower()
    if suffix not in FORMATS:
        raise AssetError(f"{shown}: not a plant mesh format agrisim reads (use {', '.join(FORMATS)})")
    if alpha_cutoff is not None and not (isinstance(alpha_cutoff, (int, float)) and 0.0 <= alpha_cutoff <= 1.0):
        raise AssetError(f"{shown}: alpha_cutoff must be within 0..1, got {alpha_cutoff!r}")
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise AssetError(f"{shown}: scale must be a positive number, got {scale!r}")
    if up not in (None, "y", "z"):
        raise AssetError(f"{shown}: up must be 'y' or 'z', got {up!r}")
    if label_names is not None and label_texture is None:
        raise AssetError(f"{shown}: label names apply to a label texture, and none was given")
    if label_texture is not None and material_labels is not None:
        raise AssetError(f"{shown}: give either a label texture or material labels, not both")

    if suffix == ".obj":
        raw = _read_obj(real, shown, root_dir)
    else:
        raw = _Gltf(real, shown, root_dir).read()

    # Frame: asset -> z-up, metres.
    v = raw.positions
    if (up or "y") == "y":
        v = np.column_stack([v[:, 0], -v[:, 2], v[:, 1]]) + 0.0  # + 0.0: no negative zeros
    if scale != 1.0:
        v = v * float(scale)
    _check_geometry(shown, v, raw.faces)

    # Labels.
    if label_texture is not None:
        materials, table = _labels_from_texture(raw, shown, label_texture, label_names, root_dir)
    elif material_labels is not None:
        materials, table = _labels_from_materials(raw, shown, material_labels)
    elif raw.labels is not None:
        materials, table = raw.materials, raw.labels
    else:
        materials = [dataclasses.replace(m, labels=None, label=1) for m in raw.materials]
        table = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "plant", ORGAN_COLORS["plant"])])
    if alpha_cutoff is not None:
        materials = [
            dataclasses.replace(m, alpha_cutoff=float(alpha_cutoff)) if m.alpha_mode != "OPAQUE" else m
            for m in materials
        ]
    _check_uvs(shown, raw, materials)

    # Size and placement.
    used = v[np.unique(raw.faces)]
    lo, hi = used.min(axis=0), used.max(axis=0)
    size = float((hi - lo).max())
    if size > max_size:
        raise AssetError(f"{shown}: the plant is {size:.4g} m across, more than {max_size:g} m{_unit_hint(size, max_size)}")
    if place:
        v = v - np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])

    plant_name = name or Path(path).stem
    try:
        mesh = Mesh(plant_name, v, raw.faces, materials, raw.face_material, raw.uvs, raw.face_instance)
    except ValueError as e:  # anything the checks above missed
        raise AssetError(f"{shown}: {e}") from None
    organs = sum(1 for lab in table.labels if lab.id != 0) > 1
    return Plant(plant_name, mesh, table, organs=organs)


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
    vy = np.column_stack([mesh.vertices[:, 0], mesh.vertices[:, 2], -mesh.vertices[:, 1]]).astype("<f4")
    attributes = {"POSITION": w.accessor(vy, 34962, minmax=True)}
    if mesh.uvs is not None:
        attributes["TEXCOORD_0"] = w.accessor(mesh.uvs.astype("<f4"), 34962)

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
            "indices": w.accessor(faces[a:b].astype("<u4").reshape(-1, 1), 34963),
            "material": int(face_material[a]),
            "mode": 4,
        }
        if face_instance is not None:
            prim["extras"] = {"agrisim": {"face_instance": w.accessor(face_instance[a:b].astype("<u2").reshape(-1, 1))}}
        primitives.append(prim)

    materials = []
    for mat in mesh.materials:
        pbr: dict[str, Any] = {
            "baseColorFactor": [float(c) for c in mat.color],
            "metallicFactor": 0.0,
            "roughnessFactor": 0.9,
        }
        extras: dict[str, Any] = {"label": int(mat.label), "alpha_cutoff": float(mat.alpha_cutoff)}
        if mat.albedo is not None:
            pbr["baseColorTexture"] = {"index": w.texture(mat.albedo, "RGBA", nearest=False)}
        if mat.labels is not None:
            extras["label_texture"] = w.texture(mat.labels, "L", nearest=True)
        m: dict[str, Any] = {
            "name": mat.name,
            "pbrMetallicRoughness": pbr,
            "alphaMode": mat.alpha_mode,
            "doubleSided": bool(mat.double_sided),
            "extras": {"agrisim": extras},
        }
        if mat.alpha_mode == "MASK":
            m["alphaCutoff"] = float(mat.alpha_cutoff)
        materials.append(m)

    gltf: dict[str, Any] = {
        "asset": {
            "version": "2.0",
            "generator": "agrisim",
            "extras": {
                "agrisim": {
                    "format": 1,
                    "labels": [{"id": lab.id, "name": lab.name, "color": [int(c) for c in lab.color]} for lab in labels.labels],
                }
            },
        },
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": mesh.name, "mesh": 0}],
        "meshes": [{"name": mesh.name, "primitives": primitives}],
        "materials": materials,
    }
    return w.finish(gltf)


# --------------------------------------------------------------------------------------------
# What a reader produces
# --------------------------------------------------------------------------------------------


@dataclass
class _Raw:
    """A mesh as read, before frames, labels and checks (positions in the asset's frame)."""

    positions: np.ndarray  # (N, 3) float64
    faces: np.ndarray  # (M, 3) int64
    face_material: np.ndarray  # (M,) int64
    materials: list[Material]
    uvs: np.ndarray | None  # (N, 2) float32, glTF convention
    has_uv: np.ndarray  # (N,) bool: did the file give this vertex a UV?
    texture_names: list[str | None] = field(default_factory=list)  # per material, for messages
    face_instance: np.ndarray | None = None
    labels: LabelTable | None = None  # an agrisim file's own label table


# --------------------------------------------------------------------------------------------
# glTF 2.0 reader
# --------------------------------------------------------------------------------------------

_COMPONENT = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
_REFUSED_EXTENSIONS = {
    "KHR_draco_mesh_compression": "Draco-compressed geometry",
    "EXT_meshopt_compression": "meshopt-compressed geometry",
    "KHR_texture_basisu": "Basis Universal (KTX2) textures",
    "EXT_mesh_gpu_instancing": "GPU instancing",
    "MSFT_texture_dds": "DDS textures",
}
_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942


class _Gltf:
    """A glTF 2.0 file (``.gltf`` with external or embedded buffers, or ``.glb``)."""

    def __init__(self, path: Path, shown: str, root: Path | None) -> None:
        self.path, self.shown, self.root = path, shown, root
        self.bin: bytes | None = None
        data = _read_bytes(path, shown)
        if data[:4] == _GLB_MAGIC:
            self.json = self._parse_glb(data)
        else:
            if path.suffix.lower() == ".glb":
                raise self.error("not a binary glTF file (it does not start with 'glTF')")
            try:
                self.json = json.loads(data.decode("utf-8-sig"))
            except (UnicodeDecodeError, json.JSONDecodeError) as e:
                raise self.error(f"not a glTF file (invalid JSON: {e})") from None
        if not isinstance(self.json, dict) or not isinstance(self.json.get("asset"), dict):
            raise self.error("not a glTF file (no 'asset' object)")
        version = str(self.json["asset"].get("version", ""))
        if not version.startswith("2."):
            raise self.error(f"glTF version {version or '?'} is not supported (agrisim reads glTF 2.0)")
        for ext in self.json.get("extensionsRequired", []) or []:
            if ext in _REFUSED_EXTENSIONS:
                raise self.error(
                    f"uses {_REFUSED_EXTENSIONS[ext]} ({ext}), which agrisim does not read: re-export it without"
                )
        self._buffers: dict[int, bytes] = {}
        self._accessors: dict[int, np.ndarray] = {}
        self._images: dict[int, Image.Image] = {}
        self._materials: dict[int | None, tuple[Material, int, tuple[float, ...] | None, str | None]] = {}
        self.agrisim = _get(self.json["asset"], "extras", "agrisim")

    def error(self, problem: str) -> AssetError:
        return AssetError(f"{self.shown}: {problem}")

    def _parse_glb(self, data: bytes) -> Any:
        if len(data) < 20:
            raise self.error("truncated binary glTF (shorter than its header)")
        _, version, length = struct.unpack_from("<4sII", data, 0)
        if version != 2:
            raise self.error(f"binary glTF version {version} is not supported (agrisim reads glTF 2.0)")
        if length > len(data):
            raise self.error(f"truncated binary glTF ({len(data)} of {length} bytes)")
        pos, doc = 12, None
        while pos + 8 <= length:
            size, kind = struct.unpack_from("<II", data, pos)
            chunk = data[pos + 8 : pos + 8 + size]
            if len(chunk) != size:
                raise self.error("truncated binary glTF (a chunk runs past the end)")
            if kind == _CHUNK_JSON and doc is None:
                try:
                    doc = json.loads(chunk.decode("utf-8"))
                except (UnicodeDecodeError, json.JSONDecodeError) as e:
                    raise self.error(f"corrupt binary glTF (invalid JSON chunk: {e})") from None
            elif kind == _CHUNK_BIN and self.bin is None:
                self.bin = chunk
            pos += 8 + size + (-size % 4)
        if doc is None:
            raise self.error("corrupt binary glTF (no JSON chunk)")
        return doc

    # -- raw data ---------------------------------------------------------------------------

    def _list(self, key: str) -> list[Any]:
        v = self.json.get(key, [])
        if not isinstance(v, list):
            raise self.error(f"'{key}' is not a list")
        return v

    def _item(self, key: str, index: Any) -> dict[str, Any]:
        items = self._list(key)
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
            raise self.error(f"refers to {key}[{index}], but the file has {len(items)}")
        item = items[index]
        if not isinstance(item, dict):
            raise self.error(f"{key}[{index}] is not an object")
        return item

    def _uri_bytes(self, uri: str, what: str) -> bytes:
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            try:
                return base64.b64decode(payload) if head.endswith(";base64") else urllib.parse.unquote_to_bytes(payload)
            except ValueError as e:
                raise self.error(f"{what}: bad data URI ({e})") from None
        if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]+://", uri):
            raise self.error(f"{what} '{uri}' is not a local file (agrisim does not download)")
        rel = urllib.parse.unquote(uri)
        real = _locate(Path(rel), self.root, f"{self.shown}: {what} '{rel}'", base=self.path.parent)
        return _read_bytes(real, f"{self.shown}: {what} '{rel}'")

    def _buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            buf = self._item("buffers", i)
            if "uri" in buf:
                data = self._uri_bytes(str(buf["uri"]), f"buffer {i}")
            elif i == 0 and self.bin is not None:
                data = self.bin
            else:
                raise self.error(f"buffer {i} has no data (no uri and no binary chunk)")
            if len(data) < int(buf.get("byteLength", 0)):
                raise self.error(f"buffer {i} is truncated ({len(data)} of {buf['byteLength']} bytes)")
            self._buffers[i] = data
        return self._buffers[i]

    def _view(self, i: int) -> tuple[memoryview, int | None]:
        bv = self._item("bufferViews", i)
        data = self._buffer(bv["buffer"])
        off, length = int(bv.get("byteOffset", 0)), int(bv["byteLength"])
        if off < 0 or off + length > len(data):
            raise self.error(f"bufferViews[{i}] runs past the end of its buffer")
        stride = bv.get("byteStride")
        return memoryview(data)[off : off + length], (int(stride) if stride else None)

    def accessor(self, i: int) -> np.ndarray:
        """Accessor ``i`` as a (count, components) array (floats if normalized)."""
        if i in self._accessors:
            return self._accessors[i]
        acc = self._item("accessors", i)
        ctype = acc.get("componentType")
        if ctype not in _COMPONENT or acc.get("type") not in _NCOMP:
            raise self.error(f"accessors[{i}] has an unknown component type or type")
        dtype, nc, count = np.dtype(_COMPONENT[ctype]), _NCOMP[acc["type"]], int(acc["count"])
        if "bufferView" in acc:
            view, stride = self._view(acc["bufferView"])
            out = _strided(view, int(acc.get("byteOffset", 0)), count, nc, dtype, stride)
            if out is None:
                raise self.error(f"accessors[{i}] runs past the end of its buffer view")
        else:
            out = np.zeros((count, nc), dtype)
        sparse = acc.get("sparse")
        if sparse:
            n = int(sparse["count"])
            ind, val = sparse["indices"], sparse["values"]
            iv, _ = self._view(ind["bufferView"])
            idx = _strided(iv, int(ind.get("byteOffset", 0)), n, 1, np.dtype(_COMPONENT[ind["componentType"]]), None)
            vv, _ = self._view(val["bufferView"])
            vals = _strided(vv, int(val.get("byteOffset", 0)), n, nc, dtype, None)
            if idx is None or vals is None or (n and int(idx.max()) >= count):
                raise self.error(f"accessors[{i}] has a malformed sparse part")
            out = out.copy()
            out[idx[:, 0].astype(np.int64)] = vals
        if acc.get("normalized") and ctype != 5126:
            out = np.maximum(out.astype(np.float64) / _NORM[ctype], -1.0).astype(np.float32)
        self._accessors[i] = out
        return out

    def image(self, i: int) -> Image.Image:
        if i not in self._images:
            img = self._item("images", i)
            what = f"image {i}" + (f" '{img['name']}'" if img.get("name") else "")
            if "uri" in img:
                data = self._uri_bytes(str(img["uri"]), what)
                what = f"image '{urllib.parse.unquote(str(img['uri']))[:80]}'"
            elif "bufferView" in img:
                view, _ = self._view(img["bufferView"])
                data = bytes(view)
            else:
                raise self.error(f"{what} has neither a uri nor a buffer view")
            self._images[i] = _decode_image(data, f"{self.shown}: {what}")
        return self._images[i]

    def texture_image(self, index: Any) -> tuple[Image.Image, str]:
        tex = self._item("textures", index)
        source = tex.get("source")
        if source is None:
            for ext_name, ext in (tex.get("extensions") or {}).items():
                if isinstance(ext, dict) and "source" in ext:
                    if ext_name in _REFUSED_EXTENSIONS:
                        raise self.error(f"texture {index} uses {_REFUSED_EXTENSIONS[ext_name]}, which agrisim does not read")
                    source = ext["source"]
                    break
        if source is None:
            raise self.error(f"texture {index} has no image")
        img = self._item("images", source)
        label = img.get("uri") if isinstance(img.get("uri"), str) and not img["uri"].startswith("data:") else None
        return self.image(source), (label or img.get("name") or f"image {source}")

    # -- materials ---------------------------------------------------------------------------

    def material(self, index: int | None) -> tuple[Material, int, tuple[float, ...] | None, str | None]:
        """(material, TEXCOORD set of its textures, KHR_texture_transform or None, texture name)."""
        if index in self._materials:
            return self._materials[index]
        if index is None:  # the spec's default material
            result = (Material("default", (1.0, 1.0, 1.0, 1.0), double_sided=False, label=1), 0, None, None)
            self._materials[None] = result
            return result
        m = self._item("materials", index)
        mname = str(m.get("name") or f"material_{index}")
        pbr = m.get("pbrMetallicRoughness") or {}
        factor = pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])
        tex_info = pbr.get("baseColorTexture")
        spec_gloss = _get(m, "extensions", "KHR_materials_pbrSpecularGlossiness")
        if tex_info is None and isinstance(spec_gloss, dict):
            tex_info = spec_gloss.get("diffuseTexture")
            factor = spec_gloss.get("diffuseFactor", factor)
        if not (isinstance(factor, list) and len(factor) == 4 and all(isinstance(c, (int, float)) for c in factor)):
            raise self.error(f"material '{mname}' has a malformed baseColorFactor")
        mode = m.get("alphaMode", "OPAQUE")
        if mode not in ("OPAQUE", "MASK", "BLEND"):
            raise self.error(f"material '{mname}' has an unknown alphaMode {mode!r}")
        extras = _get(m, "extras", "agrisim") if self.agrisim is not None else None
        cutoff = m.get("alphaCutoff", 0.5)
        if isinstance(extras, dict) and "alpha_cutoff" in extras:
            cutoff = extras["alpha_cutoff"]
        if not (isinstance(cutoff, (int, float)) and 0.0 <= cutoff <= 1.0):
            raise self.error(f"material '{mname}' has alphaCutoff {cutoff!r}, outside 0..1")

        albedo, texcoord, transform, tex_name = None, 0, None, None
        if tex_info is not None:
            img, tex_name = self.texture_image(tex_info.get("index"))
            albedo = _rgba(img)
            texcoord = int(tex_info.get("texCoord", 0))
            tt = _get(tex_info, "extensions", "KHR_texture_transform")
            if isinstance(tt, dict):
                texcoord = int(tt.get("texCoord", texcoord))
                off, rot, sc = tt.get("offset", [0.0, 0.0]), float(tt.get("rotation", 0.0)), tt.get("scale", [1.0, 1.0])
                if (off, rot, sc) != ([0.0, 0.0], 0.0, [1.0, 1.0]):
                    transform = (float(off[0]), float(off[1]), rot, float(sc[0]), float(sc[1]))

        labels, label = None, 1
        if isinstance(extras, dict):
            label = extras.get("label", 1)
            if not isinstance(label, int) or not 0 <= label <= 255:
                raise self.error(f"material '{mname}' has a malformed agrisim label {label!r}")
            if "label_texture" in extras:
                img, lname = self.texture_image(extras["label_texture"])
                if img.mode not in ("L", "P", "I;16", "I", "1"):
                    raise self.error(f"material '{mname}': label texture {lname} is not a single-channel image of label ids")
                labels = _label_ids_plain(img, f"{self.shown}: label texture {lname}")
                if albedo is not None and labels.shape != albedo.shape[:2]:
                    raise self.error(
                        f"material '{mname}': label texture {lname} is {labels.shape[1]}x{labels.shape[0]} but its "
                        f"albedo is {albedo.shape[1]}x{albedo.shape[0]}; they must match texel for texel"
                    )
                if tex_name is None:
                    tex_name = lname
        mat = Material(
            mname,
            color=tuple(float(c) for c in factor),  # type: ignore[arg-type]
            albedo=albedo,
            labels=labels,
            label=label,
            alpha_mode=mode,
            alpha_cutoff=float(cutoff),
            double_sided=bool(m.get("doubleSided", False)),
        )
        self._materials[index] = (mat, texcoord, transform, tex_name)
        return self._materials[index]

    # -- scene graph -------------------------------------------------------------------------

    def read(self) -> _Raw:
        try:
            return self._read()
        except (KeyError, IndexError, TypeError, ValueError, AttributeError, struct.error) as e:
            if isinstance(e, UserError):
                raise
            raise self.error(f"malformed glTF ({type(e).__name__}: {e})") from None

    def _roots(self) -> list[int]:
        scenes = self._list("scenes")
        if scenes:
            scene = self._item("scenes", self.json.get("scene", 0))
            return list(scene.get("nodes", []))
        nodes = self._list("nodes")
        children = {c for n in nodes for c in n.get("children", [])}
        return [i for i in range(len(nodes)) if i not in children]

    def _read(self) -> _Raw:
        n_materials = len(self._list("materials"))
        positions: list[np.ndarray] = []
        uvs: list[np.ndarray] = []
        has_uv: list[np.ndarray] = []
        faces: list[np.ndarray] = []
        face_mat: list[np.ndarray] = []
        face_inst: list[np.ndarray] = []
        any_instance = False
        seen: dict[tuple[Any, ...], int] = {}
        count = 0
        visit = 0
        used_default = False
        stack: list[tuple[int, np.ndarray, int]] = [(r, np.eye(4), 0) for r in reversed(self._roots())]
        if not self._list("meshes"):
            raise self.error("not a mesh: the file has no meshes")
        while stack:
            node_i, parent_T, depth = stack.pop()
            if depth > 256:
                raise self.error("the node hierarchy has a cycle")
            node = self._item("nodes", node_i)
            T = parent_T @ _node_matrix(node)
            for child in reversed(node.get("children", [])):
                stack.append((child, T, depth + 1))
            if "mesh" not in node:
                continue
            visit += 1
            identity = np.array_equal(T, np.eye(4))
            flip = np.linalg.det(T[:3, :3]) < 0
            mesh = self._item("meshes", node["mesh"])
            mname = mesh.get("name") or f"mesh {node['mesh']}"
            for pi, prim in enumerate(mesh.get("primitives", [])):
                attrs = prim.get("attributes", {})
                mode = prim.get("mode", 4)
                if "POSITION" not in attrs or mode not in (4, 5, 6):
                    continue  # points and lines have no surface
                mat_i = prim.get("material")
                mat, texcoord, transform, tex_name = self.material(mat_i)
                if mat_i is None:
                    used_default = True
                pos = self.accessor(attrs["POSITION"])
                if pos.shape[1] != 3:
                    raise self.error(f"{mname} primitive {pi}: POSITION is not a VEC3 accessor")
                n = len(pos)
                where = f"{mname} primitive {pi} (material '{mat.name}')"
                uv_key = f"TEXCOORD_{texcoord}"
                textured = mat.albedo is not None or mat.labels is not None
                uv = None
                if uv_key in attrs:
                    uv = self.accessor(attrs[uv_key])
                    if uv.shape[1] != 2:
                        raise self.error(f"{where}: {uv_key} is not a VEC2 accessor")
                    if len(uv) != n:
                        raise self.error(f"{where}: {uv_key} has {len(uv)} UVs for {n} vertices")
                elif textured:
                    raise self.error(f"{where} uses texture '{tex_name}' but has no UVs ({uv_key})")
                key = (visit, attrs["POSITION"], attrs.get(uv_key), transform)
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
                    base = seen[key] = count
                    count += n
                if "indices" in prim:
                    idx = self.accessor(prim["indices"])
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
                inst_acc = _get(prim, "extras", "agrisim", "face_instance") if self.agrisim is not None else None
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
        raw = _Raw(
            positions=np.concatenate(positions),
            faces=np.concatenate(faces),
            face_material=np.concatenate(face_mat),
            materials=materials,
            uvs=np.concatenate(uvs) if any_uv else None,
            has_uv=np.concatenate(has_uv),
            texture_names=names,
            face_instance=np.concatenate(face_inst) if any_instance else None,
        )
        if self.agrisim is not None:
            raw.labels = self._label_table(materials)
        return raw

    def _label_table(self, materials: list[Material]) -> LabelTable | None:
        entries = self.agrisim.get("labels") if isinstance(self.agrisim, dict) else None
        if entries is None:
            return None
        try:
            table = LabelTable([Label(int(e["id"]), str(e["name"]), tuple(int(c) for c in e["color"])) for e in entries])  # type: ignore[arg-type]
        except (KeyError, TypeError, ValueError) as e:
            raise self.error(f"malformed agrisim label table ({e})") from None
        known = {lab.id for lab in table.labels}
        for mat in materials:
            used = {mat.label} if mat.labels is None else set(np.flatnonzero(np.bincount(mat.labels.ravel(), minlength=256)).tolist())
            if not used <= known:
                raise self.error(f"material '{mat.name}' uses label ids {sorted(used - known)}, which the file's label table does not list")
        return table


def _node_matrix(node: dict[str, Any]) -> np.ndarray:
    if "matrix" in node:
        m = np.asarray(node["matrix"], dtype=np.float64)
        if m.shape != (16,):
            raise ValueError(f"node matrix must have 16 numbers, got {m.shape}")
        return m.reshape(4, 4).T  # column-major
    T = np.eye(4)
    t = node.get("translation", [0.0, 0.0, 0.0])
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    s = node.get("scale", [1.0, 1.0, 1.0])
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


def _strided(buf: memoryview, offset: int, count: int, nc: int, dtype: np.dtype, stride: int | None) -> np.ndarray | None:
    size = nc * dtype.itemsize
    stride = stride or size
    if count == 0:
        return np.zeros((0, nc), dtype)
    if offset < 0 or offset + (count - 1) * stride + size > len(buf):
        return None
    arr = np.ndarray((count, nc), dtype=dtype, buffer=buf, offset=offset, strides=(stride, dtype.itemsize))
    return arr.copy()


def _get(obj: Any, *keys: str) -> Any:
    for k in keys:
        if not isinstance(obj, dict):
            return None
        obj = obj.get(k)
    return obj


# --------------------------------------------------------------------------------------------
# OBJ + MTL reader
# --------------------------------------------------------------------------------------------

_MTL_OPTION_ARGS = {
    "-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
    "-texres": 1, "-type": 1, "-mm": 2, "-o": 3, "-s": 3, "-t": 3,
}  # fmt: skip


@dataclass
class _MtlMaterial:
    name: str
    kd: tuple[float, float, float] = (0.8, 0.8, 0.8)
    d: float = 1.0
    map_kd: tuple[dict[str, list[str]], str] | None = None
    map_d: tuple[dict[str, list[str]], str] | None = None
    source: str = ""  # the MTL file, for messages
    folder: Path = Path(".")


def _read_obj(path: Path, shown: str, root: Path | None) -> _Raw:
    data = _read_bytes(path, shown)
    if b"\x00" in data[:4096]:
        raise AssetError(f"{shown}: not a mesh (a binary file, not a text OBJ)")
    text = data.decode("utf-8", errors="replace")
    text = re.sub(r"\\\r?\n", " ", text)  # line continuations

    v_rows: list[list[str]] = []
    vt_rows: list[list[str]] = []
    corner_v: list[int] = []
    corner_vt: list[int] = []
    face_mat: list[int] = []
    mat_names: list[str] = []
    mat_index: dict[str, int] = {}
    current = -1
    mtllibs: list[str] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line[0] == "#":
            continue
        key, _, rest = line.partition(" ")
        if "\t" in key:
            key, _, rest = line.replace("\t", " ").partition(" ")
        if key == "v":
            parts = rest.split()
            if len(parts) < 3:
                raise AssetError(f"{shown}: line {lineno}: a vertex needs 3 coordinates")
            v_rows.append(parts[:3])
        elif key == "vt":
            parts = rest.split()
            if not parts:
                raise AssetError(f"{shown}: line {lineno}: a texture coordinate needs a value")
            vt_rows.append([parts[0], parts[1] if len(parts) > 1 else "0"])
        elif key == "f":
            nv, nt = len(v_rows), len(vt_rows)
            vs, ts = [], []
            try:
                for tok in rest.split():
                    sub = tok.split("/")
                    i = int(sub[0])
                    vs.append(i - 1 if i > 0 else nv + i if i < 0 else -(10**12))
                    if len(sub) > 1 and sub[1]:
                        j = int(sub[1])
                        ts.append(j - 1 if j > 0 else nt + j if j < 0 else -(10**12))
                    else:
                        ts.append(-1)
            except ValueError:
                raise AssetError(f"{shown}: line {lineno}: malformed face {rest.strip()!r}") from None
            if len(vs) < 3:
                raise AssetError(f"{shown}: line {lineno}: a face needs at least 3 vertices")
            if min(vs) < 0:
                raise AssetError(f"{shown}: line {lineno}: face refers to a vertex that does not exist")
            if any(t < -1 for t in ts):
                raise AssetError(f"{shown}: line {lineno}: face refers to a texture coordinate that does not exist")
            if current < 0:
                current = mat_index.setdefault("default", len(mat_names))
                if current == len(mat_names):
                    mat_names.append("default")
            for k in range(1, len(vs) - 1):  # fan
                corner_v += [vs[0], vs[k], vs[k + 1]]
                corner_vt += [ts[0], ts[k], ts[k + 1]]
                face_mat.append(current)
        elif key == "usemtl":
            mname = rest.strip() or "default"
            if mname not in mat_index:
                mat_index[mname] = len(mat_names)
                mat_names.append(mname)
            current = mat_index[mname]
        elif key == "mtllib":
            mtllibs.append(rest.strip())

    if not v_rows and not corner_v:
        raise AssetError(f"{shown}: not a mesh (no OBJ vertex or face statements)")
    if not corner_v:
        raise AssetError(f"{shown}: no triangles (the OBJ has vertices but no faces)")
    try:
        positions = np.array(v_rows, dtype=np.float64)
        texcoords = np.array(vt_rows, dtype=np.float64).reshape(-1, 2)
    except ValueError as e:
        raise AssetError(f"{shown}: a vertex or texture coordinate is not a number ({e})") from None
    cv = np.asarray(corner_v, np.int64)
    ct = np.asarray(corner_vt, np.int64)
    if cv.max() >= len(positions):
        raise AssetError(f"{shown}: a face refers to vertex {int(cv.max()) + 1}, but the file has {len(positions)}")
    if ct.max(initial=-1) >= len(texcoords):
        raise AssetError(
            f"{shown}: a face refers to texture coordinate {int(ct.max()) + 1}, but the file has {len(texcoords)}"
        )

    library = _read_mtllibs(mtllibs, path, shown, root)
    materials, transforms, tex_names = [], [], []
    for mname in mat_names:
        mat, transform, tex_name = _obj_material(library.get(mname), mname, shown, root)
        materials.append(mat)
        transforms.append(transform)
        tex_names.append(tex_name)

    # One agrisim vertex per distinct (position, texture coordinate, texture transform).
    fm = np.repeat(np.asarray(face_mat, np.int64), 3)
    tf_ids = {t: i for i, t in enumerate(dict.fromkeys(t for t in transforms if t is not None), 1)}
    corner_tf = np.array([tf_ids.get(t, 0) if t else 0 for t in transforms], np.int64)[fm]
    keys = (cv * (len(texcoords) + 1) + (ct + 1)) * (len(tf_ids) + 1) + corner_tf
    uniq, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # vertices in order of first use
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    corner_vertex = rank[inverse.ravel()]
    first_corner = first[order]
    vertex_pos = cv[first_corner]
    vertex_vt = ct[first_corner]
    vertex_tf = corner_tf[first_corner]

    has_uv = vertex_vt >= 0
    uvs = None
    if has_uv.any():
        st = np.where(has_uv[:, None], texcoords[np.maximum(vertex_vt, 0)], 0.0)
        inv_tf = {i: t for t, i in tf_ids.items()}
        for i, (su, sv, ou, ov) in inv_tf.items():
            sel = vertex_tf == i
            st[sel] = st[sel] * [su, sv] + [ou, ov]
        uvs = np.column_stack([st[:, 0], np.where(has_uv, 1.0 - st[:, 1], 0.0)]).astype(np.float32)  # OBJ v is up
    return _Raw(
        positions=positions[vertex_pos],
        faces=corner_vertex.reshape(-1, 3),
        face_material=np.asarray(face_mat, np.int64),
        materials=materials,
        uvs=uvs,
        has_uv=has_uv,
        texture_names=tex_names,
    )


def _read_mtllibs(names: list[str], obj: Path, shown: str, root: Path | None) -> dict[str, _MtlMaterial]:
    library: dict[str, _MtlMaterial] = {}
    for name in names:
        rel = name.replace("\\", "/")
        where = f"{shown}: material library '{rel}'"
        candidates = [rel] if (obj.parent / rel).exists() or " " not in rel else [rel, *rel.split()]
        found = False
        for cand in candidates:
            real = _locate(Path(cand), root, where, base=obj.parent, must_exist=False)
            if real.is_file():
                _parse_mtl(_read_bytes(real, where).decode("utf-8", errors="replace"), real, where, library)
                found = True
        if not found:
            raise AssetError(f"{where} not found (next to the OBJ, in {obj.parent})")
    return library


def _parse_mtl(text: str, path: Path, where: str, library: dict[str, _MtlMaterial]) -> None:
    cur: _MtlMaterial | None = None
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line[0] == "#":
            continue
        parts = line.split(None, 1)
        key, rest = parts[0].lower(), (parts[1].strip() if len(parts) > 1 else "")
        try:
            if key == "newmtl":
                cur = library.setdefault(rest, _MtlMaterial(rest, source=where, folder=path.parent))
            elif cur is None:
                continue
            elif key == "kd":
                vals = [float(x) for x in rest.split()[:3]]
                cur.kd = (vals[0], vals[0], vals[0]) if len(vals) == 1 else (vals[0], vals[1], vals[2])
            elif key == "d":
                cur.d = float(rest.split()[-1])  # "d -halo 0.5" keeps the value
            elif key in ("map_kd", "map_d"):
                setattr(cur, key, _texture_statement(rest))
        except (ValueError, IndexError):
            raise AssetError(f"{where}: line {lineno}: malformed {parts[0]} statement") from None


def _texture_statement(rest: str) -> tuple[dict[str, list[str]], str]:
    """Options and file name of a ``map_*`` statement (the file name may contain spaces)."""
    tokens = list(re.finditer(r"\S+", rest))
    opts: dict[str, list[str]] = {}
    i = 0
    while i < len(tokens) and tokens[i].group().lower() in _MTL_OPTION_ARGS:
        opt = tokens[i].group().lower()
        n = _MTL_OPTION_ARGS[opt]
        i += 1
        vals = []
        while len(vals) < n and i < len(tokens) - 1:  # never eat the file name
            tok = tokens[i].group()
            if n == 3 and vals and not _is_number(tok):
                break
            vals.append(tok)
            i += 1
        opts[opt] = vals
    if i >= len(tokens):
        raise ValueError("no file name")
    return opts, rest[tokens[i].start() :].strip()


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _obj_material(
    m: _MtlMaterial | None, name: str, shown: str, root: Path | None
) -> tuple[Material, tuple[float, float, float, float] | None, str | None]:
    """The agrisim material of an MTL material, its UV transform (su, sv, ou, ov) and texture name."""
    if m is None:  # usemtl without a library entry: plain grey
        return Material(name, (0.8, 0.8, 0.8, 1.0), label=1, double_sided=True), None, None
    rgb, albedo, mode, tex_name, transform = m.kd, None, "OPAQUE", None, None
    if m.map_kd is not None:
        opts, fname = m.map_kd
        img = _obj_texture(m, fname, root)
        albedo = _rgba(img).copy()
        rgb, tex_name = (1.0, 1.0, 1.0), fname
        if albedo[..., 3].min() < 255:
            mode = "MASK"
        transform = _mtl_uv_transform(opts)
    if m.map_d is not None:
        opts, fname = m.map_d
        alpha = _matte(_obj_texture(m, fname, root), (opts.get("-imfchan") or ["m"])[0])
        if albedo is None:
            albedo = np.full((*alpha.shape, 4), 255, np.uint8)
            tex_name = fname
            transform = _mtl_uv_transform(opts)
        elif alpha.shape != albedo.shape[:2]:
            h, w = albedo.shape[:2]
            alpha = np.asarray(Image.fromarray(alpha, "L").resize((w, h), Image.NEAREST))
        albedo[..., 3] = alpha
        mode = "MASK"
    d = float(m.d)
    if not 0.0 <= d <= 1.0:
        raise AssetError(f"{m.source}: material '{name}' has dissolve d {d}, outside 0..1")
    if d < 1.0 and mode == "OPAQUE":
        mode = "BLEND"
    mat = Material(
        name,
        color=(float(rgb[0]), float(rgb[1]), float(rgb[2]), d),
        albedo=albedo,
        label=1,
        alpha_mode=mode,  # type: ignore[arg-type]
        alpha_cutoff=0.5,
        double_sided=True,
    )
    return mat, transform, tex_name


def _mtl_uv_transform(opts: dict[str, list[str]]) -> tuple[float, float, float, float] | None:
    """MTL ``-s`` scale and ``-o`` offset of texture coordinates: (su, sv, ou, ov) or None."""
    try:
        s = [float(x) for x in opts.get("-s", [])]
        o = [float(x) for x in opts.get("-o", [])]
    except ValueError:
        return None
    t = (s[0] if s else 1.0, s[1] if len(s) > 1 else 1.0, o[0] if o else 0.0, o[1] if len(o) > 1 else 0.0)
    return None if t == (1.0, 1.0, 0.0, 0.0) else t


def _obj_texture(m: _MtlMaterial, fname: str, root: Path | None) -> Image.Image:
    rel = fname.replace("\\", "/")
    where = f"{m.source}: texture '{fname}'"
    real = _locate(Path(rel), root, where, base=m.folder, must_exist=False)
    if not real.is_file():  # exporters often write absolute paths of the author's machine
        alt = _locate(Path(Path(rel).name), root, where, base=m.folder, must_exist=False)
        if not alt.is_file():
            raise AssetError(f"{where} not found (looked in {m.folder})")
        real = alt
    return _decode_image(_read_bytes(real, where), where)


def _matte(img: Image.Image, channel: str) -> np.ndarray:
    """The opacity an MTL ``map_d`` image gives (``-imfchan`` r, g, b, m = matte, l = luminance)."""
    channel = channel.lower()
    rgba = _rgba(img)
    if channel in ("r", "g", "b"):
        return rgba[..., "rgb".index(channel)].copy()
    has_alpha = img.mode in ("RGBA", "LA", "PA", "La", "RGBa") or (img.mode == "P" and "transparency" in img.info)
    if channel == "m" and has_alpha:
        return rgba[..., 3].copy()
    return np.asarray(Image.fromarray(rgba[..., :3], "RGB").convert("L"))


# --------------------------------------------------------------------------------------------
# Labels
# --------------------------------------------------------------------------------------------


def _table(entries: list[tuple[int, str, tuple[int, int, int] | None]]) -> LabelTable:
    labels = [Label(0, "background", (0, 0, 0))]
    for k, (i, n, c) in enumerate(entries):
        labels.append(Label(i, n, c or ORGAN_COLORS.get(n) or _MORE_COLORS[k % len(_MORE_COLORS)]))
    return LabelTable(labels)


def _labels_from_materials(raw: _Raw, shown: str, material_labels: Mapping[str, str]) -> tuple[list[Material], LabelTable]:
    if not isinstance(material_labels, Mapping) or not all(
        isinstance(k, str) and isinstance(v, str) and v for k, v in material_labels.items()
    ):
        raise AssetError(f"{shown}: material labels must map material names (or patterns) to organ names")
    organs = [o for o in dict.fromkeys(material_labels.values()) if o != "background"]
    ids = {o: i for i, o in enumerate(organs, 1)}
    ids["background"] = 0
    if len(organs) > 255:
        raise AssetError(f"{shown}: at most 255 organ labels, got {len(organs)}")
    used = np.zeros(len(raw.materials), bool)
    used[np.unique(raw.face_material)] = True
    names = [m.name for m in raw.materials]
    matched: set[str] = set()
    out, missing = [], []
    for i, mat in enumerate(raw.materials):
        pattern = next((p for p in material_labels if fnmatch.fnmatchcase(mat.name, p)), None)
        if pattern is None:
            if used[i]:
                missing.append(mat.name)
            out.append(dataclasses.replace(mat, labels=None, label=0))
            continue
        matched.add(pattern)
        out.append(dataclasses.replace(mat, labels=None, label=ids[material_labels[pattern]]))
    unknown = [p for p in material_labels if p not in matched]
    if unknown:
        raise AssetError(f"{shown}: material labels {unknown} match no material; its materials are {sorted(set(names))}")
    if missing:
        raise AssetError(f"{shown}: materials {sorted(set(missing))} have no label; give a label for each (patterns allowed)")
    return out, _table([(ids[o], o, None) for o in organs])


def _labels_from_texture(
    raw: _Raw,
    shown: str,
    label_texture: str | os.PathLike[str],
    label_names: Mapping[int | str, str] | None,
    root: Path | None,
) -> tuple[list[Material], LabelTable]:
    lshown = str(label_texture)
    real = _locate(Path(label_texture), root, lshown, base=root)
    img = _decode_image(_read_bytes(real, lshown), lshown)
    ids, entries = _label_ids(img, lshown, label_names or {})
    if not any(i != 0 for i, _, _ in entries):
        raise AssetError(f"{lshown}: the label texture holds only background (0); it labels nothing as plant")
    out = []
    for i, mat in enumerate(raw.materials):
        if mat.albedo is not None and mat.albedo.shape[:2] != ids.shape:
            h, w = mat.albedo.shape[:2]
            raise AssetError(
                f"{lshown}: label texture is {ids.shape[1]}x{ids.shape[0]} but the albedo of material "
                f"'{mat.name}' in {shown} is {w}x{h}; they must match texel for texel"
            )
        out.append(dataclasses.replace(mat, labels=ids, label=0))
    return out, _table(entries)


def _label_ids_plain(img: Image.Image, shown: str) -> np.ndarray:
    if img.mode in ("I;16", "I;16B", "I;16L", "I"):
        a = np.asarray(img)
        if a.size and (a.max() > 255 or a.min() < 0):
            raise AssetError(f"{shown}: label ids must be within 0..255, found {int(a.max())}")
        return a.astype(np.uint8)
    if img.mode == "1":
        return np.asarray(img).astype(np.uint8)
    if img.mode == "LA":
        return np.asarray(img.getchannel("L")).copy()
    return np.asarray(img).astype(np.uint8, copy=True)  # L, P (palette indices are the ids)


def _label_ids(
    img: Image.Image, shown: str, names: Mapping[int | str, str]
) -> tuple[np.ndarray, list[tuple[int, str, tuple[int, int, int] | None]]]:
    """Label ids of a label texture and its (id, name, colour) entries (module doc)."""
    colour_mode = False
    if img.mode in ("L", "LA", "P", "1", "I;16", "I;16B", "I;16L", "I"):
        ids = _label_ids_plain(img, shown)
    elif img.mode in ("RGB", "RGBA"):
        rgb = np.asarray(img.convert("RGB"))
        if np.array_equal(rgb[..., 0], rgb[..., 1]) and np.array_equal(rgb[..., 0], rgb[..., 2]):
            ids = rgb[..., 0].copy()
        else:
            colour_mode = True
    else:
        raise AssetError(f"{shown}: a label texture must be an image of label ids (grey or palette) or of flat label colours, not mode {img.mode}")

    if not colour_mode:
        present = [int(i) for i in np.flatnonzero(np.bincount(ids.ravel(), minlength=256)) if i != 0]
        named = [int(k) for k in names if isinstance(k, int)]
        all_ids = sorted(set(present) | {i for i in named if 0 < i < 256})
        palette = None
        if img.mode == "P" and img.getpalette():
            palette = np.asarray(img.getpalette()[: 256 * 3], np.uint8).reshape(-1, 3)
        entries = []
        for i in all_ids:
            default = "plant" if all_ids == [1] else f"label_{i}"
            colour = tuple(int(c) for c in palette[i]) if palette is not None and i < len(palette) else None
            entries.append((i, str(names.get(i, default)), colour))  # type: ignore[arg-type]
        return ids, entries  # type: ignore[return-value]

    flat = rgb.reshape(-1, 3)
    code = (flat[:, 0].astype(np.int64) << 16) | (flat[:, 1].astype(np.int64) << 8) | flat[:, 2]
    colours, inverse, counts = np.unique(code, return_inverse=True, return_counts=True)
    if len(colours) > _MAX_LABEL_COLOURS:
        raise AssetError(
            f"{shown}: label texture has {len(colours)} distinct colours, too many for flat labels "
            "(a photo, or a smoothed or JPEG-compressed texture?); use one flat colour or one id per label"
        )
    non_black = [(int(-counts[k]), int(colours[k]), k) for k in range(len(colours)) if colours[k] != 0]
    non_black.sort()
    lut = np.zeros(len(colours), np.uint8)
    by_colour = {v: k for k, v in ORGAN_COLORS.items() if k != "plant"}
    lower = {str(k).lower(): v for k, v in names.items() if isinstance(k, str)}
    entries = []
    for new_id, (_, code_k, k) in enumerate(non_black, 1):
        colour = ((code_k >> 16) & 255, (code_k >> 8) & 255, code_k & 255)
        hexname = "#%02x%02x%02x" % colour
        default = "plant" if len(non_black) == 1 else by_colour.get(colour, f"label_{hexname[1:]}")
        lut[k] = new_id
        entries.append((new_id, lower.get(hexname, default), colour))
    return lut[inverse.ravel()].reshape(rgb.shape[:2]), entries


# --------------------------------------------------------------------------------------------
# Checks, files, images
# --------------------------------------------------------------------------------------------


def _check_geometry(shown: str, v: np.ndarray, faces: np.ndarray) -> None:
    bad = ~np.all(np.isfinite(v), axis=1)
    if bad.any():
        raise AssetError(f"{shown}: {int(bad.sum())} vertices are NaN or infinite (the first is vertex {int(np.argmax(bad))})")
    if len(faces) == 0:
        raise AssetError(f"{shown}: no triangles")
    a, b, c = (v[faces[:, i]] for i in range(3))
    with np.errstate(over="ignore", invalid="ignore"):  # absurd sizes are refused later, by size
        area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if not np.any(area > 0):
        raise AssetError(f"{shown}: every triangle is degenerate (zero area)")


def _check_uvs(shown: str, raw: _Raw, materials: list[Material]) -> None:
    for i, mat in enumerate(materials):
        if mat.albedo is None and mat.labels is None:
            continue
        corners = raw.faces[raw.face_material == i]
        if len(corners) == 0:
            continue
        missing = ~raw.has_uv[corners].all(axis=1)
        if missing.any():
            tex = raw.texture_names[i] if i < len(raw.texture_names) else None
            what = f"texture '{tex}'" if tex and mat.albedo is not None else "a label texture"
            raise AssetError(
                f"{shown}: material '{mat.name}' uses {what} but {int(missing.sum())} of its "
                f"{len(corners)} triangles have no UVs (texture coordinates)"
            )


def _unit_hint(size: float, max_size: float) -> str:
    for factor, unit in ((0.01, "centimetres"), (0.001, "millimetres"), (0.0254, "inches")):
        if 0.02 <= size * factor <= max_size:
            return f" (is it in {unit}? then load it with scale={factor:g})"
    return " (check its units; scale= rescales it)"


def _root_dir(root: str | os.PathLike[str] | None) -> Path | None:
    if root is None:
        return None
    real = Path(root).expanduser().resolve()
    if not real.is_dir():
        raise AssetError(f"{root}: the asset root is not a directory")
    return real


def _locate(path: Path, root: Path | None, shown: str, base: Path | None, must_exist: bool = True) -> Path:
    """The real path of ``path`` (relative to ``base``), refusing escapes out of ``root``."""
    path = path.expanduser()
    full = path if path.is_absolute() or base is None else base / path
    if root is not None:
        lexical = Path(os.path.normpath(full if full.is_absolute() else Path.cwd() / full))
        if not lexical.is_relative_to(root):
            raise AssetError(f"{shown}: outside the asset root {root} (paths may not leave it with '..' or absolute paths)")
        real = lexical.resolve()
        if not real.is_relative_to(root):
            raise AssetError(f"{shown}: a symlink out of the asset root {root} (to {real})")
    else:
        real = full.resolve()
    if must_exist:
        if not real.exists():
            raise AssetError(f"{shown}: no such file")
        if real.is_dir():
            raise AssetError(f"{shown}: is a directory, not a file")
    return real


def _read_bytes(path: Path, shown: str) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise AssetError(f"{shown}: no such file") from None
    except IsADirectoryError:
        raise AssetError(f"{shown}: is a directory, not a file") from None
    except OSError as e:
        raise AssetError(f"{shown}: cannot be read ({e.strerror or e})") from None


def _decode_image(data: bytes, shown: str) -> Image.Image:
    try:
        img = Image.open(io.BytesIO(data))
        img.load()
    except UnidentifiedImageError:
        raise AssetError(f"{shown}: not an image Pillow can read") from None
    except (OSError, SyntaxError, ValueError) as e:
        raise AssetError(f"{shown}: not an image Pillow can read ({e})") from None
    if img.width < 1 or img.height < 1:
        raise AssetError(f"{shown}: an empty image")
    return img


def _rgba(img: Image.Image) -> np.ndarray:
    """H x W x 4 uint8 of any Pillow image (16-bit grey scaled to 8 bits)."""
    if img.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        a = np.asarray(img).astype(np.float64)
        a = a / 257.0 if img.mode.startswith("I") and a.size and a.max() > 255 else a * (255.0 if img.mode == "F" else 1.0)
        g = np.clip(np.rint(a), 0, 255).astype(np.uint8)
        return np.dstack([g, g, g, np.full_like(g, 255)])
    return np.asarray(img.convert("RGBA")).copy()


# --------------------------------------------------------------------------------------------
# GLB writer
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

    def finish(self, gltf: dict[str, Any]) -> bytes:
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
                struct.pack("<4sII", _GLB_MAGIC, 2, total),
                struct.pack("<II", len(doc), _CHUNK_JSON),
                doc,
                struct.pack("<II", len(self.blob), _CHUNK_BIN),
                bytes(self.blob),
            ]
        )
