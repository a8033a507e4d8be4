"""A glTF 2.0 document and its binary data, for agrisim's readers.

pygltflib parses the file (``.glb`` chunks, or ``.gltf`` JSON) into its object model; this module
adds what it leaves to its users: accessors as numpy arrays (strided, sparse, normalized), images
decoded, buffers and images from data URIs or files confined to the asset root, and one clear
error naming the file for whatever is wrong with it."""

from __future__ import annotations

import base64
import dataclasses
import json
import re
import struct
import urllib.parse
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from pygltflib import GLTF2, Attributes  # type: ignore[import-untyped]  # (pygltflib ships no type hints)

from agrisim.plugins.formats.asset_reading import AssetError, decode_image, locate, read_bytes_of

_COMPONENT = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0, 5125: 4294967295.0}
_FLOAT = 5126
# decoded by none of agrisim's readers: refused with what they are rather than read as garbage
_REFUSED_EXTENSIONS = {
    "KHR_draco_mesh_compression": "Draco-compressed geometry",
    "EXT_meshopt_compression": "meshopt-compressed geometry",
    "KHR_texture_basisu": "Basis Universal (KTX2) textures",
    "EXT_mesh_gpu_instancing": "GPU instancing",
    "MSFT_texture_dds": "DDS textures",
}
_GLB_MAGIC = b"glTF"


class GltfDocument:
    """A glTF 2.0 file (``.gltf`` with external or embedded buffers, or ``.glb``): ``gltf`` is
    pygltflib's document; ``agrisim`` the ``asset.extras.agrisim`` of agrisim's own files (None
    in anyone else's)."""

    def __init__(self, path: Path, shown: str, root: Path | None) -> None:
        self.path, self.shown, self.root = path, shown, root
        self.gltf = self._parse(read_bytes_of(path, shown))
        version = str(self.gltf.asset.version or "")
        if not version.startswith("2."):
            raise self.error(f"glTF version {version or '?'} is not supported (agrisim reads glTF 2.0)")
        for ext in self.gltf.extensionsRequired or []:
            if ext in _REFUSED_EXTENSIONS:
                raise self.error(
                    f"uses {_REFUSED_EXTENSIONS[ext]} ({ext}), which agrisim does not read: re-export it without"
                )
        self._buffers: dict[int, bytes] = {}
        self._accessors: dict[int, np.ndarray] = {}
        self._images: dict[int, Image.Image] = {}
        self.agrisim = get(self.gltf.asset.extras, "agrisim")

    def error(self, problem: str) -> AssetError:
        """An error naming this file."""
        return AssetError(f"{self.shown}: {problem}")

    def _parse(self, data: bytes) -> GLTF2:
        glb = data[:4] == _GLB_MAGIC
        if glb:
            # pygltflib only warns about another GLB version and reads past a short file's end
            if len(data) < 20:
                raise self.error("truncated binary glTF (shorter than its header)")
            _, version, length = struct.unpack_from("<4sII", data, 0)
            if version != 2:
                raise self.error(f"binary glTF version {version} is not supported (agrisim reads glTF 2.0)")
            if length > len(data):
                raise self.error(f"truncated binary glTF ({len(data)} of {length} bytes)")
        elif self.path.suffix.lower() == ".glb":
            raise self.error("not a binary glTF file (it does not start with 'glTF')")
        try:
            doc = GLTF2.load_from_bytes(data) if glb else GLTF2.from_json(data.decode("utf-8-sig"))
        except (UnicodeDecodeError, json.JSONDecodeError) as e:
            raise self.error(
                f"corrupt binary glTF (invalid JSON chunk: {e})" if glb else f"not a glTF file (invalid JSON: {e})"
            ) from None
        except (AttributeError, KeyError, TypeError, ValueError, struct.error) as e:
            # pygltflib's decoder fails this way on JSON that is not glTF's structure
            raise self.error(f"not a glTF file (its JSON does not have glTF's structure: {e})") from None
        if doc is None:
            raise self.error("corrupt binary glTF (no JSON chunk)")
        return doc

    # -- the document's parts ------------------------------------------------------------------

    def items(self, key: str) -> list[Any]:
        """The document's list ``key`` ("meshes", "nodes", ...)."""
        return getattr(self.gltf, key) or []

    def item(self, key: str, index: Any) -> Any:
        """Entry ``index`` of the document's list ``key``, refusing an index it does not have."""
        items = self.items(key)
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
            raise self.error(f"refers to {key}[{index}], but the file has {len(items)}")
        return items[index]

    def plain_list(self, key: str) -> list[Any]:
        """The document's list ``key`` as the JSON objects it is in the file (how
        :mod:`agrisim.plugins.sinks.dataset.scene_glb` reads its scenes' nodes)."""
        return [plain(x) for x in self.items(key)]

    def plain_item(self, key: str, index: Any) -> Any:
        """:meth:`item` as the JSON object it is in the file."""
        return plain(self.item(key, index))

    # -- raw data ------------------------------------------------------------------------------

    def _uri_bytes(self, uri: str, what: str) -> bytes:
        # By hand: pygltflib decodes only base64 octet-stream data URIs and opens any path it is given.
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
            buf = self.item("buffers", i)
            blob = self.gltf.binary_blob()
            if buf.uri is not None:
                data = self._uri_bytes(str(buf.uri), f"buffer {i}")
            elif i == 0 and blob is not None:
                data = bytes(blob)
            else:
                raise self.error(f"buffer {i} has no data (no uri and no binary chunk)")
            if len(data) < int(buf.byteLength or 0):
                raise self.error(f"buffer {i} is truncated ({len(data)} of {buf.byteLength} bytes)")
            self._buffers[i] = data
        return self._buffers[i]

    def _view(self, i: int) -> tuple[memoryview, int | None]:
        bv = self.item("bufferViews", i)
        data = self._buffer(bv.buffer)
        off, length = int(bv.byteOffset or 0), int(bv.byteLength)
        if off < 0 or off + length > len(data):
            raise self.error(f"bufferViews[{i}] runs past the end of its buffer")
        stride = bv.byteStride
        return memoryview(data)[off : off + length], (int(stride) if stride else None)

    # By hand: pygltflib leaves accessors as bytes, and trimesh's decoder (private) skips sparse
    # and normalized accessors.
    def accessor(self, i: int) -> np.ndarray:
        """Accessor ``i`` as a (count, components) array (floats if normalized)."""
        if i in self._accessors:
            return self._accessors[i]
        acc = self.item("accessors", i)
        ctype = acc.componentType
        if ctype not in _COMPONENT or acc.type not in _NCOMP:
            raise self.error(f"accessors[{i}] has an unknown component type or type")
        dtype, nc, count = np.dtype(_COMPONENT[ctype]), _NCOMP[acc.type], int(acc.count)
        if acc.bufferView is not None:
            view, stride = self._view(acc.bufferView)
            out = _strided(view, int(acc.byteOffset or 0), count, nc, dtype, stride)
            if out is None:
                raise self.error(f"accessors[{i}] runs past the end of its buffer view")
        else:
            out = np.zeros((count, nc), dtype)
        sparse = acc.sparse
        if sparse:
            n = int(sparse.count)
            ind, val = sparse.indices, sparse.values
            iv, _ = self._view(ind.bufferView)
            idx = _strided(iv, int(ind.byteOffset or 0), n, 1, np.dtype(_COMPONENT[ind.componentType]), None)
            vv, _ = self._view(val.bufferView)
            vals = _strided(vv, int(val.byteOffset or 0), n, nc, dtype, None)
            if idx is None or vals is None or (n and int(idx.max()) >= count):
                raise self.error(f"accessors[{i}] has a malformed sparse part")
            out = out.copy()
            out[idx[:, 0].astype(np.int64)] = vals
        if acc.normalized and ctype != _FLOAT:
            out = np.maximum(out.astype(np.float64) / _NORM[ctype], -1.0).astype(np.float32)
        self._accessors[i] = out
        return out

    def image(self, i: int) -> Image.Image:
        """Image ``i``, decoded (from the binary chunk, a data URI or a file)."""
        if i not in self._images:
            img = self.item("images", i)
            what = f"image {i}" + (f" '{img.name}'" if img.name else "")
            if img.uri is not None:
                data = self._uri_bytes(str(img.uri), what)
                what = f"image '{urllib.parse.unquote(str(img.uri))[:80]}'"
            elif img.bufferView is not None:
                view, _ = self._view(img.bufferView)
                data = bytes(view)
            else:
                raise self.error(f"{what} has neither a uri nor a buffer view")
            self._images[i] = decode_image(data, f"{self.shown}: {what}")
        return self._images[i]

    def texture_image(self, index: Any) -> tuple[Image.Image, str]:
        """The image of texture ``index`` and a name for it in messages."""
        tex = self.item("textures", index)
        source = tex.source
        if source is None:
            for ext_name, ext in (tex.extensions or {}).items():
                if isinstance(ext, dict) and "source" in ext:
                    if ext_name in _REFUSED_EXTENSIONS:
                        raise self.error(
                            f"texture {index} uses {_REFUSED_EXTENSIONS[ext_name]}, which agrisim does not read"
                        )
                    source = ext["source"]
                    break
        if source is None:
            raise self.error(f"texture {index} has no image")
        img = self.item("images", source)
        label = img.uri if isinstance(img.uri, str) and not img.uri.startswith("data:") else None
        return self.image(source), (label or img.name or f"image {source}")


def _strided(
    buf: memoryview, offset: int, count: int, nc: int, dtype: np.dtype, stride: int | None
) -> np.ndarray | None:
    size = nc * dtype.itemsize
    stride = stride or size
    if count == 0:
        return np.zeros((0, nc), dtype)
    if offset < 0 or offset + (count - 1) * stride + size > len(buf):
        return None
    arr = np.ndarray((count, nc), dtype=dtype, buffer=buf, offset=offset, strides=(stride, dtype.itemsize))
    return arr.copy()


def get(obj: Any, *keys: str) -> Any:
    """``obj[k1][k2]...`` of JSON objects (a pygltflib object's fields too), None where absent."""
    for k in keys:
        if isinstance(obj, dict):
            obj = obj.get(k)
        elif dataclasses.is_dataclass(obj) or isinstance(obj, Attributes):
            obj = getattr(obj, k, None)
        else:
            return None
    return obj


def plain(obj: Any) -> Any:
    """A pygltflib object as the JSON it stands for (unset fields left out)."""
    if isinstance(obj, Attributes):
        return {k: v for k, v in vars(obj).items() if v is not None}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: plain(v) for f in dataclasses.fields(obj) if (v := getattr(obj, f.name)) is not None}
    if isinstance(obj, list):
        return [plain(v) for v in obj]
    return obj
