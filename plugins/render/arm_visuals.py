"""The arms' visual geometry as agrisim meshes, one per link, in the link's frame.

Every ``<visual>`` of the URDF (COLLADA/STL meshes through trimesh, boxes, cylinders, spheres) is
baked with its ``link_T_visual`` and scale; each sub-mesh keeps its own flat colour (the UR10's
COLLADA files colour their parts: dark joints, blue caps, grey tubes), else the URDF material's,
else a neutral grey. A renderer places link ``L`` at ``link_poses[robot][L]`` (``world_T_link``).

Decimated meshes come from two places. The cell's own arm (the UR10 with its camera, exactly
:func:`agrisim.robot.urdf.ur10_with_camera`'s URDF and mesh files) at the renderers' default
budget is shipped precomputed (:data:`PRECOMPUTED`, written by ``scripts/arm_meshes.py`` with
Open3D's quadric decimation, which drew every default run's arms before), so that the default
run's images stay what they were and no renderer needs Open3D. Any other URDF, budget or mesh
file is decimated here by fast-simplification.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agrisim.plugins.render import robot_meshes
from agrisim.scene.colour import srgb_to_linear
from agrisim.scene.model import Material, Mesh
from agrisim.util import cache as util_cache

if TYPE_CHECKING:
    import trimesh

log = logging.getLogger(__name__)

#: colour of visuals whose files and URDF give none (linear RGBA)
DEFAULT_COLOR = (0.45, 0.45, 0.47, 1.0)
#: the camera body added to the flange by agrisim.robot.urdf (linear RGBA)
CAMERA_COLOR = (0.02, 0.02, 0.02, 1.0)

#: bump when the meshes this module makes change for the same inputs (the disk cache's key)
VISUALS_VERSION = 2

#: the cell's arm decimated to the renderers' default budget by Open3D (``scripts/arm_meshes.py``)
PRECOMPUTED = Path(__file__).with_name("arm_meshes_ur10.npz")
#: the layout of :data:`PRECOMPUTED`; a file of another is not read
PRECOMPUTED_FORMAT = 1

#: (vertices, faces, linear RGBA) of one sub-mesh of a visual
_Part = tuple[np.ndarray, np.ndarray, tuple[float, float, float, float]]
#: decimates one part, ``(vertices, faces, target triangles) -> (vertices, faces)``
Decimator = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]


@dataclass
class LinkMesh:
    """One link's visual triangles in its own frame."""

    link: str
    mesh: Mesh


@dataclass(frozen=True)
class VisualInputs:
    """What the visual meshes of a URDF are made from, named by content.

    ``urdf_sha256`` digests the URDF text without its ``<collision>`` elements (they draw
    nothing) and with each visual mesh file's name replaced by the digest of its contents: the
    URDF names its files by absolute paths, which differ between installations of the same
    files. ``meshes`` holds each visual mesh file's name (without its folder) and the SHA-256
    of its contents, in the URDF's order; ``complete`` says whether every one could be read.
    """

    urdf_sha256: str
    meshes: tuple[tuple[str, str], ...]
    complete: bool


def visual_inputs(urdf: str) -> VisualInputs:
    """The :class:`VisualInputs` of the URDF text ``urdf`` (reads each visual mesh file)."""
    root = ET.fromstring(urdf)
    digests: dict[str, str] = {}
    complete = True
    for link in root.iter("link"):
        for collision in link.findall("collision"):
            link.remove(collision)
        for mesh in (m for visual in link.findall("visual") for m in visual.iter("mesh")):
            name = mesh.get("filename", "")
            if name not in digests:
                try:
                    digests[name] = hashlib.sha256(Path(name).read_bytes()).hexdigest()
                except OSError:
                    digests[name] = "missing"
                    complete = False
            # the suffix too: trimesh picks the reader by it
            mesh.set("filename", f"sha256:{digests[name]}{Path(name).suffix}")
    text = ET.tostring(root, encoding="unicode")
    return VisualInputs(
        urdf_sha256=hashlib.sha256(text.encode()).hexdigest(),
        meshes=tuple((Path(name).name, digest) for name, digest in digests.items()),
        complete=complete,
    )


def _primitive(visual: robot_meshes.Visual) -> trimesh.Trimesh | None:
    import trimesh

    if visual.kind == "box" and visual.size:
        return trimesh.creation.box(extents=visual.size)
    if visual.kind == "cylinder" and visual.radius and visual.length:
        return trimesh.creation.cylinder(radius=visual.radius, height=visual.length, sections=32)
    if visual.kind == "sphere" and visual.radius:
        return trimesh.creation.icosphere(subdivisions=3, radius=visual.radius)
    return None


def _parts(visual: robot_meshes.Visual) -> list[_Part]:
    """(vertices in the visual's frame, faces, linear RGBA) of each sub-mesh of one visual."""
    urdf_color: tuple[float, float, float, float] | None = None
    if visual.rgba:
        r, g, b = (float(x) for x in srgb_to_linear(visual.rgba[:3]))
        urdf_color = (r, g, b, 1.0)
    if visual.kind != "mesh":
        prim = _primitive(visual)
        if prim is None:
            return []
        color = urdf_color or (CAMERA_COLOR if visual.link == "camera_link" else DEFAULT_COLOR)
        return [(np.asarray(prim.vertices, float), np.asarray(prim.faces, np.int64), color)]
    scene = robot_meshes.load_scene(visual.filename)  # type: ignore[arg-type]
    out: list[_Part] = []
    scale = np.asarray(visual.scale, float)
    for node in scene.graph.nodes_geometry:
        T, name = scene.graph[node]
        geom = scene.geometry[name]
        if not hasattr(geom, "faces") or len(geom.faces) == 0:
            continue
        v = np.asarray(geom.vertices, float) @ T[:3, :3].T + T[:3, 3]
        color = urdf_color or DEFAULT_COLOR
        material = getattr(getattr(geom, "visual", None), "material", None)
        main = getattr(material, "main_color", None)
        if urdf_color is None and main is not None:
            rgb = srgb_to_linear(np.asarray(main[:3], float) / 255.0)
            color = (float(rgb[0]), float(rgb[1]), float(rgb[2]), 1.0)
        out.append((v * scale, np.asarray(geom.faces, np.int64), color))
    return out


def _decimate(v: np.ndarray, f: np.ndarray, target: float) -> tuple[np.ndarray, np.ndarray]:
    """Quadric edge-collapse decimation to about ``target`` triangles (fast-simplification)."""
    import fast_simplification

    # COLLADA parts repeat a vertex for each face along their seams; fast-simplification moves
    # such seam vertices apart, opening gaps of centimetres in the UR10's parts, unless the
    # copies are one vertex
    v, inverse = np.unique(v, axis=0, return_inverse=True)
    f = inverse.reshape(-1)[f]
    v, f = fast_simplification.simplify(v, f, target_count=max(int(target), 4))
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    used, f = np.unique(f, return_inverse=True)
    return np.asarray(v, float)[used], f.reshape(-1, 3).astype(np.int64)


def _material(link: str, index: int, color: tuple[float, float, float, float]) -> Material:
    """The ``index``-th flat-coloured material of ``link``'s mesh."""
    return Material(f"{link}/{index}", color=color, double_sided=True, roughness=0.45)


def _precomputed_meta(path: Path) -> dict[str, Any] | None:
    """What the precomputed meshes at ``path`` were made from, or None without a readable file."""
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        log.debug("precomputed arm meshes %s unreadable: %s", path, exc)
        return None
    return meta if isinstance(meta, dict) and meta.get("format") == PRECOMPUTED_FORMAT else None


def precomputed_applies(inputs: VisualInputs, max_triangles: int, path: Path = PRECOMPUTED) -> bool:
    """Whether the precomputed meshes at ``path`` were made from exactly ``inputs`` at
    ``max_triangles`` (the same URDF, the same mesh file contents, the same budget)."""
    meta = _precomputed_meta(path)
    return (
        inputs.complete
        and meta is not None
        and meta.get("max_triangles") == max_triangles
        and meta.get("urdf_sha256") == inputs.urdf_sha256
        and [tuple(m) for m in meta.get("meshes", ())] == list(inputs.meshes)
    )


def read_precomputed(path: Path = PRECOMPUTED) -> tuple[LinkMesh, ...]:
    """The link meshes kept at ``path`` by :func:`write_precomputed`."""
    links: list[LinkMesh] = []
    with np.load(path, allow_pickle=False) as data:
        for i, link in enumerate(str(name) for name in data["links"]):
            colors = [(float(r), float(g), float(b), float(a)) for r, g, b, a in data[f"{i}/colors"]]
            materials = [_material(link, k, color) for k, color in enumerate(colors)]
            mesh = Mesh(link, data[f"{i}/vertices"], data[f"{i}/faces"], materials, data[f"{i}/face_material"])
            links.append(LinkMesh(link, mesh))
    return tuple(links)


def write_precomputed(path: Path, links: tuple[LinkMesh, ...], meta: dict[str, Any]) -> None:
    """Keep ``links`` at ``path`` as a compressed NumPy archive, with ``meta`` (what they were
    made from; ``format`` is set here). The same meshes give the same bytes: members carry no
    time, so a file made again from unchanged inputs leaves git nothing to commit."""
    arrays: dict[str, np.ndarray] = {
        "meta": np.array(json.dumps({**meta, "format": PRECOMPUTED_FORMAT}, sort_keys=True)),
        "links": np.array([lm.link for lm in links]),
    }
    for i, lm in enumerate(links):
        if [m.name for m in lm.mesh.materials] != [f"{lm.link}/{k}" for k in range(len(lm.mesh.materials))]:
            raise ValueError(f"link {lm.link!r}: materials not made by this module")
        arrays[f"{i}/vertices"] = lm.mesh.vertices
        arrays[f"{i}/faces"] = lm.mesh.faces
        arrays[f"{i}/face_material"] = lm.mesh.face_material
        arrays[f"{i}/colors"] = np.array([m.color for m in lm.mesh.materials], np.float64)
    with zipfile.ZipFile(path, "w") as archive:
        for name, array in arrays.items():
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, array, allow_pickle=False)
            member = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            member.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(member, buffer.getvalue(), compresslevel=9)


def _cache_entry(urdf: str, max_triangles: int, inputs: VisualInputs, precomputed: str | None) -> Path:
    """Where the meshes of ``urdf`` at ``max_triangles`` are kept, named by everything they are
    made from: the URDF, each mesh file's contents, the precomputed file when they are read from
    it (its digest, else none), the libraries that read and decimate the files, this module's
    version."""
    libraries = []
    for package in ("trimesh", "fast-simplification"):
        try:
            libraries.append(f"{package} {metadata.version(package)}")
        except metadata.PackageNotFoundError:
            libraries.append(f"{package} none")
    files = [f"{name}|{digest}" for name, digest in inputs.meshes]
    ident = "\n".join(
        [urdf, str(max_triangles), f"v{VISUALS_VERSION}", f"precomputed {precomputed or 'none'}", *libraries, *files]
    )
    return util_cache.cache_dir("arm-visuals") / f"{hashlib.sha256(ident.encode()).hexdigest()[:24]}.pickle"


@lru_cache(maxsize=8)
def arm_link_meshes(urdf: str, max_triangles: int = 0) -> tuple[LinkMesh, ...]:
    """The visual meshes of every link of ``urdf`` that has any, in the link's frame (cached per
    URDF text: both arms of a cell share the work; and on disk, so that later processes read
    them instead of loading the mesh files and decimating again, 0.5-1.7 s a process).

    ``max_triangles`` > 0 decimates the arm to about that many triangles in all, each part
    keeping its share (quadric edge collapse keeps the silhouette; parts stay separate, so
    colours keep their borders). The cell's own arm at the renderers' default budget is read
    from :data:`PRECOMPUTED` (Open3D's decimation, made once); anything else is decimated by
    fast-simplification, which meets the budget to a few percent down to about 15000 triangles
    for the UR10 and falls short of it below (about 7000 at the least: it refuses collapses that
    would fold a face over).
    """
    inputs = visual_inputs(urdf)
    precomputed = None
    if max_triangles > 0 and precomputed_applies(inputs, max_triangles, PRECOMPUTED):
        precomputed = hashlib.sha256(PRECOMPUTED.read_bytes()).hexdigest()
    path = _cache_entry(urdf, max_triangles, inputs, precomputed)
    kept = util_cache.read_pickle(path)
    if isinstance(kept, tuple) and all(isinstance(lm, LinkMesh) for lm in kept):
        return kept
    links = read_precomputed(PRECOMPUTED) if precomputed else _link_meshes(urdf, max_triangles)
    # a visual that failed to load is not kept: it may load next time
    if inputs.complete:
        util_cache.write_pickle(path, links)
    return links


def _link_meshes(urdf: str, max_triangles: int, decimate: Decimator | None = None) -> tuple[LinkMesh, ...]:
    """:func:`arm_link_meshes`, made from the URDF's files; ``decimate`` decimates each part
    (else :func:`_decimate`; ``scripts/arm_meshes.py`` passes Open3D's)."""
    decimate = decimate or _decimate
    loaded: list[tuple[str, robot_meshes.Visual, list[_Part]]] = []
    for link, visuals in robot_meshes.link_visuals(urdf).items():
        for visual in visuals:
            try:
                loaded.append((link, visual, _parts(visual)))
            except (OSError, ValueError) as exc:
                log.warning("link %r: visual %s not loaded (%s); drawn without it", link, visual.filename, exc)
    total = sum(len(f) for _, _, parts in loaded for _, f, _ in parts)
    ratio = max_triangles / total if 0 < max_triangles < total else 1.0
    links: list[LinkMesh] = []
    for link in dict.fromkeys(name for name, _, _ in loaded):
        verts: list[np.ndarray] = []
        faces: list[np.ndarray] = []
        fmat: list[np.ndarray] = []
        materials: list[Material] = []
        colors: dict[tuple[float, ...], int] = {}
        n = 0
        for _, visual, parts in (x for x in loaded if x[0] == link):
            for v, f, color in parts:
                if ratio < 1.0 and len(f) > 200:
                    v, f = decimate(v, f, len(f) * ratio)
                v = v @ visual.link_T_visual[:3, :3].T + visual.link_T_visual[:3, 3]
                if color not in colors:
                    colors[color] = len(materials)
                    materials.append(_material(link, len(materials), color))
                verts.append(v)
                faces.append(f + n)
                fmat.append(np.full(len(f), colors[color], np.int32))
                n += len(v)
        if materials:
            mesh = Mesh(link, np.concatenate(verts), np.concatenate(faces), materials, np.concatenate(fmat))
            links.append(LinkMesh(link, mesh))
    return tuple(links)
