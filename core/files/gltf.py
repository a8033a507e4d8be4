"""The glTF 2.0 reader (``.gltf`` with external or embedded buffers, and ``.glb``): meshes,
node transforms, materials and agrisim's own ``extras``, into a :class:`RawMesh`.
:mod:`agrisim.files.plant_asset` documents what is honoured."""

from __future__ import annotations

import base64
import json
import math
import re
import struct
import urllib.parse
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from agrisim.errors import UserError
from agrisim.scene.colour import linear_to_srgb, srgb_to_linear
from agrisim.scene.model import LabelTable, Material

from agrisim.files.asset_reading import AssetError, label_ids_plain, RawMesh, decode_image, locate, read_bytes_of, rgba_array

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
GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942


class _Gltf:
    """A glTF 2.0 file (``.gltf`` with external or embedded buffers, or ``.glb``)."""

    def __init__(self, path: Path, shown: str, root: Path | None) -> None:
        self.path, self.shown, self.root = path, shown, root
        self.bin: bytes | None = None
        data = read_bytes_of(path, shown)
        if data[:4] == GLB_MAGIC:
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
            if kind == CHUNK_JSON and doc is None:
                try:
                    doc = json.loads(chunk.decode("utf-8"))
                except (UnicodeDecodeError, json.JSONDecodeError) as e:
                    raise self.error(f"corrupt binary glTF (invalid JSON chunk: {e})") from None
            elif kind == CHUNK_BIN and self.bin is None:
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
        real = locate(Path(rel), self.root, f"{self.shown}: {what} '{rel}'", base=self.path.parent)
        return read_bytes_of(real, f"{self.shown}: {what} '{rel}'")

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
            self._images[i] = decode_image(data, f"{self.shown}: {what}")
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
            albedo = rgba_array(img)
            texcoord, transform = _texture_placement(tex_info)
        maps = _MapReader(self, mname, None if tex_info is None else (texcoord, transform))

        labels, label = None, 1
        if isinstance(extras, dict):
            label = extras.get("label", 1)
            if not isinstance(label, int) or not 0 <= label <= 255:
                raise self.error(f"material '{mname}' has a malformed agrisim label {label!r}")
            if "label_texture" in extras:
                img, lname = self.texture_image(extras["label_texture"])
                if img.mode not in ("L", "P", "I;16", "I", "1"):
                    raise self.error(f"material '{mname}': label texture {lname} is not a single-channel image of label ids")
                labels = label_ids_plain(img, f"{self.shown}: label texture {lname}")
                if albedo is not None and labels.shape != albedo.shape[:2]:
                    raise self.error(
                        f"material '{mname}': label texture {lname} is {labels.shape[1]}x{labels.shape[0]} but its "
                        f"albedo is {albedo.shape[1]}x{albedo.shape[0]}; they must match texel for texel"
                    )
                if tex_name is None:
                    tex_name = lname
        color, roughness, metallic, transmittance = self._look(m, pbr, factor, extras)
        albedo, color, transmission = self._transmission(m, extras, maps, albedo, color)
        normal = m.get("normalTexture")
        normal_map = maps.rgb(normal, "normalTexture")
        normal_scale = float(normal.get("scale", 1.0)) if normal_map is not None else 1.0
        if not (math.isfinite(normal_scale) and normal_scale >= 0.0):
            raise self.error(f"material '{mname}' has normalTexture.scale {normal_scale!r}; it must be >= 0")
        if maps.placement is not None:
            texcoord, transform = maps.placement
        mat = Material(
            mname,
            color=color,
            albedo=albedo,
            labels=labels,
            label=label,
            alpha_mode=mode,
            alpha_cutoff=float(cutoff),
            double_sided=bool(m.get("doubleSided", False)),
            roughness=roughness,
            metallic=metallic,
            transmittance=None if transmission is not None else transmittance,
            transmission=transmission,
            metallic_roughness=maps.rgb(pbr.get("metallicRoughnessTexture"), "metallicRoughnessTexture"),
            normal_map=normal_map,
            normal_scale=normal_scale,
        )
        self._materials[index] = (mat, texcoord, transform, tex_name)
        return self._materials[index]

    @staticmethod
    def _look(m: dict, pbr: dict, factor: list, extras: Any) -> tuple[tuple, float, float, tuple | None]:
        """(colour factor, roughness, metallic, transmittance) of a material: glTF's defaults
        (metallic and rough) where the file is silent; agrisim's own files carry their
        transmittance (per unit of albedo) in extras."""
        color = tuple(float(c) for c in factor)
        roughness, metallic = _unit(pbr.get("roughnessFactor", 1.0)), _unit(pbr.get("metallicFactor", 1.0))
        transmittance = None
        if isinstance(extras, dict) and isinstance(extras.get("transmittance"), list):
            transmittance = tuple(max(float(t), 0.0) for t in extras["transmittance"][:3])
        return color, roughness, metallic, transmittance  # type: ignore[return-value]

    def _transmission(
        self, m: dict, extras: Any, maps: _MapReader, albedo: np.ndarray | None, color: tuple
    ) -> tuple[np.ndarray | None, tuple, np.ndarray | None]:
        """(albedo, colour factor, transmission texture) under diffuse transmission.

        KHR_materials_diffuse_transmission mixes a diffuse reflector of the base colour and a
        diffuse transmitter of its own colour, a fraction f = factor x texture alpha going
        through: the reflected part becomes the albedo x (1 - f) (in the colour factor when f
        is constant, else texel by texel on the albedo's grid) and the transmitted colour f x
        colour factor x colour texture becomes agrisim's transmission texture. agrisim's own
        files keep theirs in extras (already split)."""
        if isinstance(extras, dict) and "transmission_texture" in extras:
            img, _ = self.texture_image(extras["transmission_texture"])
            return albedo, color, np.asarray(img.convert("RGB")).copy()
        ext = _get(m, "extensions", "KHR_materials_diffuse_transmission")
        if not isinstance(ext, dict):
            return albedo, color, None
        f = _unit(ext.get("diffuseTransmissionFactor", 0.0))
        tint = [_unit(t) for t in (ext.get("diffuseTransmissionColorFactor") or [1.0, 1.0, 1.0])[:3]]
        f_tex = maps.rgba(ext.get("diffuseTransmissionTexture"), "diffuseTransmissionTexture")
        tint_tex = maps.rgba(ext.get("diffuseTransmissionColorTexture"), "diffuseTransmissionColorTexture")
        if f == 0.0:
            return albedo, color, None
        # the transmitted colour, linear, on the grid of whichever texture has one
        grid = next((t for t in (tint_tex, f_tex) if t is not None), np.zeros((1, 1, 4), np.uint8))
        f_map = f if f_tex is None else f * _resample(f_tex, grid.shape[:2])[..., 3:4] / 255.0
        through = f_map * np.asarray(tint) * (1.0 if tint_tex is None else srgb_to_linear(tint_tex[..., :3] / 255.0))
        transmission = _srgb8(np.broadcast_to(through, (*grid.shape[:2], 3)))
        if f_tex is None:
            color = (*(c * (1.0 - f) for c in color[:3]), color[3])
        else:
            base = albedo if albedo is not None else np.full((*f_tex.shape[:2], 4), 255, np.uint8)
            keep = 1.0 - f * _resample(f_tex, base.shape[:2])[..., 3:4] / 255.0
            albedo = np.dstack([_srgb8(srgb_to_linear(base[..., :3] / 255.0) * keep), base[..., 3]])
        return albedo, color, transmission

    # -- scene graph -------------------------------------------------------------------------

    def read(self) -> RawMesh:
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

    # One pass over the document's nodes and primitives; accessors and images are helpers.
    def _read(self) -> RawMesh:
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
        raw = RawMesh(
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
            table = LabelTable.from_json(entries)
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


def _unit(x: Any) -> float:
    return min(max(float(x), 0.0), 1.0)


def _texture_placement(info: dict) -> tuple[int, tuple[float, ...] | None]:
    """(TEXCOORD set, KHR_texture_transform or None) of a texture reference."""
    texcoord, transform = int(info.get("texCoord", 0)), None
    tt = _get(info, "extensions", "KHR_texture_transform")
    if isinstance(tt, dict):
        texcoord = int(tt.get("texCoord", texcoord))
        off, rot, sc = tt.get("offset", [0.0, 0.0]), float(tt.get("rotation", 0.0)), tt.get("scale", [1.0, 1.0])
        if (off, rot, sc) != ([0.0, 0.0], 0.0, [1.0, 1.0]):
            transform = (float(off[0]), float(off[1]), rot, float(sc[0]), float(sc[1]))
    return texcoord, transform


def _srgb8(linear: np.ndarray) -> np.ndarray:
    return np.round(linear_to_srgb(np.clip(linear, 0.0, 1.0)) * 255.0).astype(np.uint8)


def _resample(texture: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``texture`` sampled nearest at the texel centres of an image of ``shape``."""
    rows = (np.arange(shape[0]) + 0.5) * texture.shape[0] // shape[0]
    cols = (np.arange(shape[1]) + 0.5) * texture.shape[1] // shape[1]
    return texture[rows.astype(np.int64)[:, None], cols.astype(np.int64)[None, :]]


class _MapReader:
    """A material's textures other than the base colour, which must share its UV placement
    (agrisim keeps one UV set per mesh); the first one fixes it when there is no base colour
    texture."""

    def __init__(self, doc: _Gltf, material: str, placement: tuple[int, tuple[float, ...] | None] | None) -> None:
        self.doc, self.material, self.placement = doc, material, placement

    def rgba(self, info: Any, what: str) -> np.ndarray | None:
        if not isinstance(info, dict):
            return None
        placement = _texture_placement(info)
        if self.placement is None:
            self.placement = placement
        elif placement != self.placement:
            raise self.doc.error(
                f"material '{self.material}': its {what} uses other texture coordinates (set or transform) than its "
                "other textures; agrisim reads one UV set per material: re-export with one"
            )
        img, _ = self.doc.texture_image(info.get("index"))
        return rgba_array(img)

    def rgb(self, info: Any, what: str) -> np.ndarray | None:
        texture = self.rgba(info, what)
        return None if texture is None else np.ascontiguousarray(texture[..., :3])


def _get(obj: Any, *keys: str) -> Any:
    for k in keys:
        if not isinstance(obj, dict):
            return None
        obj = obj.get(k)
    return obj


def read_gltf(path: Path, shown: str, root: Path | None) -> RawMesh:
    """Read the glTF file at ``path`` (``shown`` names it in errors; ``root`` confines the files it refers to)."""
    return _Gltf(path, shown, root).read()
