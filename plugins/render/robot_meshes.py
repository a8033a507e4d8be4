"""Robot link visuals read from a URDF, and their meshes converted for viewers.

A URDF's ``<visual>`` elements name mesh files in whatever format the robot's authors chose; the
UR10 of ``example-robot-data`` uses COLLADA (``.dae``), which Rerun's ``Asset3D`` does not read.
:func:`glb_bytes` converts any mesh trimesh can load to binary glTF once and keeps the result in
memory for the process and on disk across processes (``$AGRISIM_CACHE_DIR/meshes``, else
``$XDG_CACHE_HOME/agrisim/meshes`` or ``~/.cache/agrisim/meshes``), keyed by the source's path,
size and modification time, so an edited mesh is converted again.

Nothing here depends on Rerun: renderers that need the arms' geometry can use
:func:`link_visuals` and :func:`load_scene` too.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from agrisim.scene.transforms import pose, rpy_matrix
from agrisim.util import cache as util_cache

if TYPE_CHECKING:
    import trimesh

log = logging.getLogger(__name__)

#: bump when the conversion changes, so that stale cache entries are not reused
CONVERTER_VERSION = 1
#: formats Rerun's Asset3D reads directly (media types); everything else is converted to GLB
NATIVE_MEDIA_TYPES = {".glb": "model/gltf-binary", ".obj": "model/obj", ".stl": "model/stl"}
GLB_MEDIA_TYPE = "model/gltf-binary"


@dataclass(frozen=True)
class Visual:
    """One ``<visual>`` of a URDF link, in the link's frame.

    ``kind`` says which of the geometry fields are set: ``mesh`` (``filename``, ``scale``),
    ``box`` (``size``, full extents), ``cylinder`` (``radius``, ``length``, along z) or
    ``sphere`` (``radius``). ``rgba`` is the URDF material colour (0..1) when it has one.
    """

    link: str
    index: int  # position among the link's visuals
    link_T_visual: np.ndarray
    kind: Literal["mesh", "box", "cylinder", "sphere"]
    filename: str | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None
    rgba: tuple[float, float, float, float] | None = None


def _floats(text: str | None, n: int, default: float) -> tuple[float, ...]:
    if not text:
        return (default,) * n
    values = [float(v) for v in text.split()]
    if len(values) == 1 and n > 1:  # a scalar mesh scale is allowed by some tools
        values = values * n
    if len(values) != n:
        raise ValueError(f"expected {n} numbers, got {text!r}")
    return tuple(values)


def _vec3(text: str | None, default: float) -> tuple[float, float, float]:
    x, y, z = _floats(text, 3, default)
    return x, y, z


def _origin(element: ET.Element) -> np.ndarray:
    origin = element.find("origin")
    if origin is None:
        return np.eye(4)
    xyz = _floats(origin.get("xyz"), 3, 0.0)
    rpy = _floats(origin.get("rpy"), 3, 0.0)
    return pose(rpy_matrix(*rpy), np.array(xyz))


def _material_rgba(visual: ET.Element, named: dict[str, tuple[float, ...]]) -> tuple[float, float, float, float] | None:
    material = visual.find("material")
    if material is None:
        return None
    color = material.find("color")
    if color is not None and color.get("rgba"):
        return tuple(_floats(color.get("rgba"), 4, 1.0))  # type: ignore[return-value]
    return named.get(material.get("name", ""))  # type: ignore[return-value]


def link_visuals(urdf: str) -> dict[str, list[Visual]]:
    """The visuals of every link of the URDF text ``urdf`` that has any, by link name.

    Mesh file names are returned as written (``package://`` URIs are not resolved here:
    :func:`agrisim.robot.urdf.ur10_with_camera` already made them absolute).
    """
    root = ET.fromstring(urdf)
    # Materials may be defined once at top level and referenced by name in visuals.
    named: dict[str, tuple[float, ...]] = {}
    for material in root.findall("material"):
        color = material.find("color")
        if material.get("name") and color is not None and color.get("rgba"):
            named[material.get("name", "")] = _floats(color.get("rgba"), 4, 1.0)
    out: dict[str, list[Visual]] = {}
    for link in root.findall("link"):
        name = link.get("name", "")
        visuals: list[Visual] = []
        for visual in link.findall("visual"):
            geometry = visual.find("geometry")
            if geometry is None or len(geometry) == 0:
                continue
            shape = geometry[0]
            common: dict[str, Any] = dict(
                link=name,
                index=len(visuals),
                link_T_visual=_origin(visual),
                rgba=_material_rgba(visual, named),
            )
            if shape.tag == "mesh":
                visuals.append(
                    Visual(kind="mesh", filename=shape.get("filename"), scale=_vec3(shape.get("scale"), 1.0), **common)
                )
            elif shape.tag == "box":
                visuals.append(Visual(kind="box", size=_vec3(shape.get("size"), 0.0), **common))
            elif shape.tag == "cylinder":
                visuals.append(
                    Visual(
                        kind="cylinder",
                        radius=float(shape.get("radius", 0)),
                        length=float(shape.get("length", 0)),
                        **common,
                    )
                )
            elif shape.tag == "sphere":
                visuals.append(Visual(kind="sphere", radius=float(shape.get("radius", 0)), **common))
            else:
                log.warning("URDF link %r: unsupported visual geometry <%s> skipped", name, shape.tag)
        if visuals:
            out[name] = visuals
    return out


# ---------------------------------------------------------------------- mesh conversion


def cache_dir() -> Path:
    """Where converted meshes are kept across processes."""
    return util_cache.cache_dir("meshes")


def _cache_key(path: Path) -> str:
    st = path.stat()
    # the installed trimesh's version, without importing it (a second of start-up when the
    # cache already holds every mesh)
    ident = f"{path.resolve()}|{st.st_size}|{st.st_mtime_ns}|v{CONVERTER_VERSION}|trimesh {metadata.version('trimesh')}"
    return hashlib.sha256(ident.encode()).hexdigest()[:20]


def load_scene(path: str | Path) -> trimesh.Scene:
    """The mesh file at ``path`` as a trimesh scene (its own units and axes, node transforms kept)."""
    import trimesh

    # force="scene" always returns a Scene; trimesh annotates load for every force (Geometry)
    return trimesh.load(str(path), force="scene")  # type: ignore[return-value]


def _convert(path: Path) -> bytes:
    scene = load_scene(path)
    if not scene.geometry:
        raise ValueError(f"{path} holds no mesh geometry")
    # Smooth vertex normals: without them the viewer shades every triangle flat.
    return scene.export(file_type="glb", include_normals=True)


_memory: dict[str, bytes] = {}
_lock = threading.Lock()


def glb_bytes(path: str | Path) -> bytes:
    """The mesh at ``path`` as binary glTF, converted once and cached (memory, then disk).

    The disk cache is best effort: an unwritable cache directory only costs a conversion per
    process. Raises ``OSError`` or ``ValueError`` when the mesh cannot be read.
    """
    path = Path(path)
    key = _cache_key(path)
    with _lock:
        if key in _memory:
            return _memory[key]
    cached = cache_dir() / f"{path.stem}-{key}.glb"
    data: bytes | None = None
    try:
        data = cached.read_bytes()
    except OSError:
        pass
    if not data:
        data = _convert(path)
        util_cache.write_cached(cached, data)
    with _lock:
        _memory[key] = data
    return data


def asset_bytes(path: str | Path) -> tuple[bytes, str]:
    """``(contents, media_type)`` for a Rerun ``Asset3D``: the file itself when Rerun reads its
    format, else its GLB conversion."""
    path = Path(path)
    media_type = NATIVE_MEDIA_TYPES.get(path.suffix.lower())
    if media_type is not None:
        return path.read_bytes(), media_type
    return glb_bytes(path), GLB_MEDIA_TYPE


__all__ = ["Visual", "link_visuals", "load_scene", "glb_bytes", "asset_bytes", "cache_dir"]
