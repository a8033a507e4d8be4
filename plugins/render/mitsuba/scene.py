"""The agrisim scene as a Mitsuba scene: meshes by material, lights, an environment map, and the
arms as meshes whose vertices follow the link poses.

Lights keep the raycast renderer's radiometric meaning (see the package docstring): an area
light becomes a one-sided ``disk`` emitter of radius r facing its direction with radiance
``colour * I / r^2``; spot and point lights get intensity ``colour * pi * I`` (Mitsuba's spot
falls off linearly in angle from 90% of the cone to its edge where raycast's is a smoothstep).
Area lights are seen by the camera as glowing discs (the ceiling panels' faces); the exact pass
does not see them, so a lamp's own pixels have RGB without depth or label.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import ConfigError
from agrisim.scene.model import Light, Mesh

from .materials import BsdfFactory, mirrored_faces
from .options import MitsubaOptions
from .vertex_tint import VertexColours
from .vertex_tint import register as register_vertex_tint

F32 = np.float32
#: readable environment maps
ENVMAP_SUFFIXES = (".exr", ".hdr", ".png", ".jpg", ".jpeg", ".pfm")


def check_envmap(path: Path) -> None:
    """Refuse an environment map that is not a readable image Mitsuba loads."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise ConfigError(f"[renderer.mitsuba] envmap {p}: no such file")
    if p.suffix.lower() not in ENVMAP_SUFFIXES:
        raise ConfigError(
            f"[renderer.mitsuba] envmap {p}: not an image Mitsuba reads (allowed: {', '.join(ENVMAP_SUFFIXES)})"
        )
    try:
        with p.open("rb") as f:
            f.read(16)
    except OSError as exc:
        raise ConfigError(f"[renderer.mitsuba] envmap {p}: cannot be read ({exc.strerror})") from None


def _frame_z(direction: np.ndarray) -> np.ndarray:
    """A rotation whose z axis is ``direction``."""
    z = np.asarray(direction, np.float64)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def light_dict(light: Light, transform: Any) -> dict:
    """The Mitsuba shape or emitter of one agrisim light (``transform`` makes a Mitsuba
    transform of a 4 x 4 array)."""
    colour = np.asarray(light.color, np.float64)
    if light.kind == "area":
        r = max(float(light.radius), 1e-4)
        T = np.eye(4)
        T[:3, :3] = _frame_z(light.direction) * r
        T[:3, 3] = light.position
        radiance = colour * light.intensity / (r * r)
        return {
            "type": "disk",
            "to_world": transform(T),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance.tolist()}},
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
        }
    intensity = (colour * math.pi * light.intensity).tolist()
    T = np.eye(4)
    T[:3, :3] = _frame_z(light.direction)
    T[:3, 3] = light.position
    if light.kind == "spot":
        cone = min(max(float(light.cone_deg), 0.1), 179.0)
        return {
            "type": "spot",
            "to_world": transform(T),
            "intensity": {"type": "rgb", "value": intensity},
            "cutoff_angle": cone,
            "beam_width": 0.9 * cone,
        }
    return {
        "type": "point",
        "position": [float(x) for x in light.position],
        "intensity": {"type": "rgb", "value": intensity},
    }


def _split(
    mesh: Mesh,
) -> Iterable[tuple[int, bool, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]]:
    """(material index, mirrored, vertices, faces, uvs, colours) of each material's part of ``mesh``, its
    vertices renumbered (Mitsuba gives a mesh one BSDF); a normal-mapped material's faces are
    split further into unmirrored and mirrored UVs (:func:`mirrored_faces`)."""
    for m in np.unique(mesh.face_material):
        faces = mesh.faces[mesh.face_material == m]
        groups = [(False, faces)]
        if mesh.materials[m].normal_map is not None and mesh.uvs is not None:
            flip = mirrored_faces(faces, mesh.uvs)
            groups = [(g, faces[flip == g]) for g in (False, True) if np.any(flip == g)]
        for mirrored, part in groups:
            used, inverse = np.unique(part, return_inverse=True)
            uvs = mesh.uvs[used] if mesh.uvs is not None else None
            colours = mesh.colors[used] if mesh.colors is not None else None
            yield int(m), mirrored, mesh.vertices[used], inverse.reshape(-1, 3).astype(np.uint32), uvs, colours


@dataclass
class ArmPart:
    """One material's triangles of one arm link, in the link's frame; ``key`` names its
    ``vertex_positions`` among the scene's parameters."""

    arm: str
    link: str
    vertices: np.ndarray  # (n, 3) float64, link frame
    key: str


@dataclass
class SceneParts:
    """What :func:`build` made: the scene dict, and the arm parts to pose per frame."""

    scene: dict
    arms: list[ArmPart] = field(default_factory=list)


def build(
    mi: Any,
    meshes: Iterable[Mesh],
    lights: Iterable[Light],
    arms: Mapping[str, Iterable[tuple[str, Mesh]]],
    options: MitsubaOptions,
    integrator: dict,
) -> SceneParts:
    """The Mitsuba scene dict of static ``meshes`` (world frame), ``lights`` and ``arms``
    (arm -> (link, mesh in the link frame)), drawn by ``integrator``."""

    def texture(data: np.ndarray, filter_type: str) -> Any:
        return mi.load_dict(
            {
                "type": "bitmap",
                "data": mi.TensorXf(data),
                "raw": True,
                "filter_type": filter_type,
                "wrap_mode": "repeat",
            }
        )

    vertex_colours = VertexColours()
    bsdfs = BsdfFactory(texture, vertex_colours)
    made: dict[tuple[int, bool, bool], Any] = {}  # (id(material), mirrored, tinted) -> BSDF, shared

    def shape(
        name: str,
        mesh: Mesh,
        m: int,
        mirrored: bool,
        v: np.ndarray,
        f: np.ndarray,
        uv: np.ndarray | None,
        colours: np.ndarray | None = None,
    ) -> Any:
        material = mesh.materials[m]
        key = (id(material), mirrored, colours is not None)
        if key not in made:
            if colours is not None:
                register_vertex_tint(mi)
            made[key] = mi.load_dict(bsdfs.bsdf(material, mirrored, tint=colours is not None))
        props = mi.Properties()
        props["bsdf"] = made[key]
        shp = mi.Mesh(name, len(v), len(f), props=props, has_vertex_normals=False, has_vertex_texcoords=uv is not None)
        params = mi.traverse(shp)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(v, F32).ravel())
        params["faces"] = mi.UInt32(np.ascontiguousarray(f, np.uint32).ravel())
        if uv is not None:
            params["vertex_texcoords"] = mi.Float(np.ascontiguousarray(uv, F32).ravel())
        params.update()
        if colours is not None:
            vertex_colours.add(mi, shp, v, f, colours)
        return shp

    scene: dict[str, Any] = {"type": "scene", "integrator": integrator}
    for i, mesh in enumerate(meshes):
        if len(mesh.faces) == 0:
            continue
        for m, mirrored, v, f, uv, colours in _split(mesh):
            scene[f"mesh_{i:03d}_{m:03d}" + ("_mirrored" if mirrored else "")] = shape(
                f"{mesh.name}/{m}", mesh, m, mirrored, v, f, uv, colours
            )
    for i, light in enumerate(lights):
        d = light_dict(light, mi.ScalarTransform4f)
        scene[f"light_{i:02d}"] = d
    if options.envmap is not None:
        # Mitsuba's environment maps are y up; the world is z up: a quarter turn about x.
        z_up = mi.ScalarTransform4f(np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]]))
        scene["envmap"] = {
            "type": "envmap",
            "filename": str(Path(options.envmap).expanduser()),
            "scale": float(options.envmap_scale),
            "to_world": z_up,
        }
    parts = SceneParts(scene)
    for a, (arm, links) in enumerate(arms.items()):
        for j, (link, mesh) in enumerate(links):
            for m, mirrored, v, f, uv, colours in _split(mesh):
                # (tinted shapes must not move: VertexColours keeps their vertices)
                assert colours is None, "arm meshes carry no vertex colours (the renderer drops them)"
                key = f"arm_{a}_{j:02d}_{m:02d}" + ("_mirrored" if mirrored else "")
                scene[key] = shape(f"{arm}/{link}/{m}", mesh, m, mirrored, v, f, uv, colours)
                parts.arms.append(ArmPart(arm, link, v, f"{key}.vertex_positions"))
    vertex_colours.finish(mi)
    return parts
