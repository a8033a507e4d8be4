"""The arms' visual geometry as agrisim meshes, one per link, in the link's frame.

Every ``<visual>`` of the URDF (COLLADA/STL meshes through trimesh, boxes, cylinders, spheres) is
baked with its ``link_T_visual`` and scale; each sub-mesh keeps its own flat colour (the UR10's
COLLADA files colour their parts: dark joints, blue caps, grey tubes), else the URDF material's,
else a neutral grey. A renderer places link ``L`` at ``link_poses[robot][L]`` (``world_T_link``).
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from agrisim.robot import meshes as robot_meshes
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
VISUALS_VERSION = 1

#: (vertices, faces, linear RGBA) of one sub-mesh of a visual
_Part = tuple[np.ndarray, np.ndarray, tuple[float, float, float, float]]


@dataclass
class LinkMesh:
    """One link's visual triangles in its own frame."""

    link: str
    mesh: Mesh


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
    """Quadric edge-collapse decimation to about ``target`` triangles (Open3D)."""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v), o3d.utility.Vector3iVector(f.astype(np.int32)))
    mesh = mesh.simplify_quadric_decimation(max(int(target), 4))
    mesh.remove_degenerate_triangles()
    mesh.remove_unreferenced_vertices()
    return np.asarray(mesh.vertices, float), np.asarray(mesh.triangles, np.int64)


def _cache_entry(urdf: str, max_triangles: int) -> tuple[Path, bool]:
    """Where the meshes of ``urdf`` at ``max_triangles`` are kept, named by everything they are
    made from (the URDF, each mesh file's path, size and time, the libraries that read and
    decimate them, this module's version); and whether every mesh file is there (a visual that
    fails to load is not kept: it may load next time)."""
    files = sorted({v.filename for vs in robot_meshes.link_visuals(urdf).values() for v in vs if v.filename})
    stats, complete = [], True
    for name in files:
        try:
            st = Path(name).stat()
            stats.append(f"{name}|{st.st_size}|{st.st_mtime_ns}")
        except OSError:
            stats.append(f"{name}|missing")
            complete = False
    libraries = []
    for package in ("trimesh", "open3d"):
        try:
            libraries.append(f"{package} {metadata.version(package)}")
        except metadata.PackageNotFoundError:
            libraries.append(f"{package} none")
    ident = "\n".join([urdf, str(max_triangles), f"v{VISUALS_VERSION}", *libraries, *stats])
    path = util_cache.cache_dir("arm-visuals") / f"{hashlib.sha256(ident.encode()).hexdigest()[:24]}.pickle"
    return path, complete


@lru_cache(maxsize=8)
def arm_link_meshes(urdf: str, max_triangles: int = 0) -> tuple[LinkMesh, ...]:
    """The visual meshes of every link of ``urdf`` that has any, in the link's frame (cached per
    URDF text: both arms of a cell share the work; and on disk, so that later processes read
    them instead of loading the mesh files and decimating again, 0.5-1.7 s a process).

    ``max_triangles`` > 0 decimates the arm to about that many triangles in all, each part
    keeping its share (quadric edge collapse keeps the silhouette; parts stay separate, so
    colours keep their borders).
    """
    path, complete = _cache_entry(urdf, max_triangles)
    kept = util_cache.read_pickle(path)
    if isinstance(kept, tuple) and all(isinstance(lm, LinkMesh) for lm in kept):
        return kept
    links = _link_meshes(urdf, max_triangles)
    if complete:
        util_cache.write_pickle(path, links)
    return links


def _link_meshes(urdf: str, max_triangles: int) -> tuple[LinkMesh, ...]:
    """:func:`arm_link_meshes`, made from the URDF's files."""
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
                    v, f = _decimate(v, f, len(f) * ratio)
                v = v @ visual.link_T_visual[:3, :3].T + visual.link_T_visual[:3, 3]
                if color not in colors:
                    colors[color] = len(materials)
                    materials.append(
                        Material(f"{link}/{len(materials)}", color=color, double_sided=True, roughness=0.45)
                    )
                verts.append(v)
                faces.append(f + n)
                fmat.append(np.full(len(f), colors[color], np.int32))
                n += len(v)
        if materials:
            mesh = Mesh(link, np.concatenate(verts), np.concatenate(faces), materials, np.concatenate(fmat))
            links.append(LinkMesh(link, mesh))
    return tuple(links)
