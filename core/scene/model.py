"""The visual scene as plain data: textured triangle meshes, materials, lights, labels.

One backend-free model that plant generators and asset loaders produce and that every renderer,
exporter and sink consumes (as :mod:`agrisim.robot.cell` is for physics).

Conventions
-----------
* Vertices in metres, in the frame the owner says (plants: plant frame, origin at the centre of
  the soil surface, z up; static scene meshes: world).
* UVs follow glTF: (0, 0) is the top-left corner of the texture image, u grows to the right,
  v grows downwards. The texel of (u, v) in an H x W image is
  ``(row, col) = (floor(v * H), floor(u * W))``, wrapped (textures repeat).
* A material's ``albedo`` is sRGB RGBA uint8; its alpha carries the shape of cut-out cards.
  ``labels`` is a uint8 image of label ids sampled *nearest* at the same UVs (the paper's label
  texture); without one, every texel has the material's constant ``label``.
* Label ids index the scene's :class:`LabelTable`; 0 is background.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

AlphaMode = Literal["OPAQUE", "MASK", "BLEND"]


#: Diffuse transmittance of a typical green leaf per unit of its reflectance, linear (R, G, B):
#: PROSPECT-D gives reflectance about (0.05, 0.14, 0.04) and transmittance about (0.03, 0.14,
#: 0.005) in the red, green and blue bands, so light through a leaf is greener than off it.
LEAF_TRANSMITTANCE = (0.6, 1.0, 0.125)
#: Roughness of a leaf's faint specular sheen (waxy cuticle)
LEAF_ROUGHNESS = 0.4


@dataclass
class Material:
    """How a set of triangles looks and is labelled."""

    name: str
    color: tuple[float, float, float, float] = (0.8, 0.8, 0.8, 1.0)
    """Linear RGBA factor (multiplies the albedo texture; the colour itself without one)."""
    albedo: np.ndarray | None = None
    """H x W x 4 uint8 sRGB + alpha texture, or None."""
    labels: np.ndarray | None = None
    """H x W uint8 label-id texture, or None for the constant ``label``."""
    label: int = 0
    """Label id of every texel when there is no label texture."""
    alpha_mode: AlphaMode = "OPAQUE"
    """glTF alpha mode: OPAQUE ignores alpha; MASK and BLEND cut away texels below the cutoff
    (a step, as the paper does, since blended edges would blend labels)."""
    alpha_cutoff: float = 0.5
    """Texels with alpha below this are holes (MASK/BLEND)."""
    double_sided: bool = True
    """Seen from both sides (leaf cards are)."""
    roughness: float = 0.8
    """Microfacet roughness of the surface's specular lobe, 0 (mirror) to 1 (matte) (glTF's
    ``roughnessFactor``). Path tracers use it; the raycast renderer shades Lambert only."""
    metallic: float = 0.0
    """0 for dielectrics (paint, clay, leaves), 1 for bare metal (glTF's ``metallicFactor``)."""
    transmittance: tuple[float, float, float] | None = None
    """Thin translucent surfaces (leaf cards): diffuse transmittance per unit of albedo, per
    linear R, G, B channel; the back-lit side then glows with ``albedo * transmittance``
    (capped so that reflected plus transmitted light never exceeds 1). None: opaque."""
    transmission: np.ndarray | None = None
    """Thin translucent surfaces whose transmitted colour is its own texture (glTF's
    KHR_materials_diffuse_transmission: factor x colour): H x W x 3 uint8 sRGB, the diffuse
    transmittance of each texel, not scaled by the albedo. Excludes ``transmittance``."""
    metallic_roughness: np.ndarray | None = None
    """glTF's metallic-roughness texture, H x W x 3 uint8, linear: green is the roughness and
    blue the metallic of each texel, times ``roughness`` and ``metallic``."""
    normal_map: np.ndarray | None = None
    """glTF's tangent-space normal texture, H x W x 3 uint8: (r, g, b) / 255 * 2 - 1 is the
    normal with x along the tangent (the direction u grows), y along the bitangent (up in the
    image: the direction v shrinks) and z along the surface normal. Path tracers use it."""
    normal_scale: float = 1.0
    """glTF's ``normalTexture.scale``: multiplies the map's x and y before normalising."""
    nir: float | None = None
    """Diffuse reflectance in the near infrared (about 850 nm, where depth cameras illuminate),
    0 to 1; None: estimated from the visible albedo (:func:`agrisim.plugins.sensors.nir.nir_reflectance`).
    Depth sensors use it; leaves are far brighter there than their green suggests."""
    back_color: tuple[float, float, float] | None = None
    """Double-sided surfaces whose back differs from their front (a leaf's lower side, paler
    than its upper side): linear R, G, B factors of the back's colour against the front's
    (capped at 1); None: both sides alike. The front is the side the face normal points to.
    Path tracers use it; glTF has no such field (agrisim's files keep it in ``extras``)."""
    back_roughness: float | None = None
    """Roughness of the back's specular lobe (a leaf's matte lower side), without the
    metallic-roughness texture (the front's); None: as the front."""

    def __post_init__(self) -> None:
        if self.albedo is not None:
            a = np.asarray(self.albedo)
            if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] != 4 or min(a.shape[:2]) < 1:
                raise ValueError(f"material {self.name!r}: albedo must be H x W x 4 uint8, got {a.dtype} {a.shape}")
        if self.labels is not None:
            lab = np.asarray(self.labels)
            if lab.dtype != np.uint8 or lab.ndim != 2 or min(lab.shape) < 1:
                raise ValueError(f"material {self.name!r}: labels must be H x W uint8, got {lab.dtype} {lab.shape}")
        if not 0.0 <= self.alpha_cutoff <= 1.0:
            raise ValueError(f"material {self.name!r}: alpha cutoff must be in [0, 1], got {self.alpha_cutoff}")
        if not (0.0 <= self.roughness <= 1.0 and 0.0 <= self.metallic <= 1.0):
            raise ValueError(f"material {self.name!r}: roughness and metallic must be in [0, 1]")
        if self.transmittance is not None and (len(self.transmittance) != 3 or min(self.transmittance) < 0.0):
            raise ValueError(f"material {self.name!r}: transmittance must be three non-negative numbers")
        for what in ("transmission", "metallic_roughness", "normal_map"):
            tex = getattr(self, what)
            if tex is not None:
                t = np.asarray(tex)
                if t.dtype != np.uint8 or t.ndim != 3 or t.shape[2] != 3 or min(t.shape[:2]) < 1:
                    raise ValueError(f"material {self.name!r}: {what} must be H x W x 3 uint8, got {t.dtype} {t.shape}")
        if self.transmission is not None and self.transmittance is not None:
            raise ValueError(f"material {self.name!r}: give transmittance or a transmission texture, not both")
        if self.back_color is not None and (
            len(self.back_color) != 3 or not all(math.isfinite(c) and c >= 0.0 for c in self.back_color)
        ):
            raise ValueError(f"material {self.name!r}: back colour must be three finite numbers >= 0")
        if self.back_roughness is not None and not 0.0 <= self.back_roughness <= 1.0:
            raise ValueError(f"material {self.name!r}: back roughness must be in [0, 1]")
        if not (math.isfinite(self.normal_scale) and self.normal_scale >= 0.0):
            raise ValueError(
                f"material {self.name!r}: normal scale must be a finite number >= 0, got {self.normal_scale}"
            )

    @property
    def cuts(self) -> bool:
        """Does opacity cut holes in this material? (glTF: alpha is the texture's alpha times
        the colour factor's.)"""
        return self.alpha_mode != "OPAQUE" and (self.albedo is not None or self.color[3] < 1.0)


@dataclass
class Mesh:
    """Triangles with per-vertex UVs and one material per triangle."""

    name: str
    vertices: np.ndarray  # (N, 3) float64
    faces: np.ndarray  # (M, 3) int32 vertex indices
    materials: list[Material]
    face_material: np.ndarray  # (M,) int32 index into ``materials``
    uvs: np.ndarray | None = None  # (N, 2) float32, glTF convention
    face_instance: np.ndarray | None = None  # (M,) uint16 leaf instance ids, 0 = none
    colors: np.ndarray | None = None
    """(N, 3) float32 linear RGB in [0, 1] per vertex (glTF's ``COLOR_0``), or None (white).
    It multiplies every colour of the vertex's material: the albedo on both sides and the
    transmitted colour (how one atlas gives every leaf its own shade)."""

    def __post_init__(self) -> None:
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int32)
        self.face_material = np.ascontiguousarray(self.face_material, dtype=np.int32)
        n, m = len(self.vertices), len(self.faces)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            raise ValueError(f"mesh {self.name!r}: vertices must be N x 3")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise ValueError(f"mesh {self.name!r}: faces must be M x 3")
        if m and (self.faces.min() < 0 or self.faces.max() >= n):
            raise ValueError(f"mesh {self.name!r}: face indices outside 0..{n - 1}")
        if not np.all(np.isfinite(self.vertices)):
            raise ValueError(f"mesh {self.name!r}: vertices must be finite")
        if self.face_material.shape != (m,):
            raise ValueError(f"mesh {self.name!r}: face_material must have one entry per face")
        if m and (self.face_material.min() < 0 or self.face_material.max() >= len(self.materials)):
            raise ValueError(f"mesh {self.name!r}: face_material indices outside the material list")
        if self.uvs is not None:
            self.uvs = np.ascontiguousarray(self.uvs, dtype=np.float32)
            if self.uvs.shape != (n, 2) or not np.all(np.isfinite(self.uvs)):
                raise ValueError(f"mesh {self.name!r}: uvs must be N x 2 and finite")
        elif any(mat.albedo is not None or mat.labels is not None for mat in self.materials):
            raise ValueError(f"mesh {self.name!r}: textured materials need uvs")
        if self.face_instance is not None:
            self.face_instance = np.ascontiguousarray(self.face_instance, dtype=np.uint16)
            if self.face_instance.shape != (m,):
                raise ValueError(f"mesh {self.name!r}: face_instance must have one entry per face")
        if self.colors is not None:
            self.colors = np.ascontiguousarray(self.colors, dtype=np.float32)
            if self.colors.shape != (n, 3) or not np.all((self.colors >= 0) & (self.colors <= 1)):
                raise ValueError(f"mesh {self.name!r}: colors must be N x 3 and within 0..1")

    def transformed(self, T: np.ndarray, name: str | None = None) -> Mesh:
        """The same mesh with vertices mapped by the 4x4 pose ``T``."""
        v = self.vertices @ T[:3, :3].T + T[:3, 3]
        return dataclasses.replace(self, name=name or self.name, vertices=v)

    @property
    def areas(self) -> np.ndarray:
        """Area of every triangle, m^2."""
        a, b, c = (self.vertices[self.faces[:, i]] for i in range(3))
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


@dataclass
class PointSet:
    """A plant drawn as points: a scan (LiDAR, photogrammetry, a reconstruction) or samples of a
    mesh's surface (``--as-points``). Each point is drawn as a sphere of diameter ``size``.

    Coordinates in the frame the owner says (a :class:`Plant`'s: the plant frame; a
    :class:`Scene`'s: world). Labels index the owner's label table (0: drawn, not plant).
    """

    positions: np.ndarray  # (N, 3) float64
    colors: np.ndarray  # (N, 3) uint8 sRGB
    labels: np.ndarray  # (N,) uint8 label ids
    instances: np.ndarray | None = None  # (N,) uint16 leaf instance ids, 0 = none
    size: float | None = None
    """Diameter of every point's sphere, m (None: not chosen yet; a scene's is always set)."""

    def __post_init__(self) -> None:
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float64)
        n = len(self.positions)
        if self.positions.ndim != 2 or self.positions.shape[1] != 3:
            raise ValueError("points: positions must be N x 3")
        if not np.all(np.isfinite(self.positions)):
            raise ValueError("points: positions must be finite")
        self.colors = np.ascontiguousarray(self.colors)
        if self.colors.dtype != np.uint8 or self.colors.shape != (n, 3):
            raise ValueError(f"points: colors must be N x 3 uint8, got {self.colors.dtype} {self.colors.shape}")
        self.labels = np.ascontiguousarray(self.labels)
        if self.labels.dtype != np.uint8 or self.labels.shape != (n,):
            raise ValueError(f"points: labels must be N uint8, got {self.labels.dtype} {self.labels.shape}")
        if self.instances is not None:
            self.instances = np.ascontiguousarray(self.instances)
            if self.instances.dtype != np.uint16 or self.instances.shape != (n,):
                raise ValueError(
                    f"points: instances must be N uint16, got {self.instances.dtype} {self.instances.shape}"
                )
        if self.size is not None and not (math.isfinite(self.size) and self.size > 0):
            raise ValueError(f"points: size must be a finite number > 0, got {self.size}")

    def __len__(self) -> int:
        return len(self.positions)

    def transformed(self, T: np.ndarray) -> PointSet:
        """The same points mapped by the 4x4 pose ``T``."""
        p = self.positions @ T[:3, :3].T + T[:3, 3]
        return PointSet(p, self.colors, self.labels, self.instances, self.size)


@dataclass(frozen=True)
class Label:
    """One entry of the label table."""

    id: int
    name: str
    color: tuple[int, int, int]  # sRGB 0..255, for labels_vis and viewers


@dataclass
class LabelTable:
    """Label ids, names and colours of a run (0 = background)."""

    labels: list[Label] = field(default_factory=lambda: [Label(0, "background", (0, 0, 0))])

    def __post_init__(self) -> None:
        ids = [lab.id for lab in self.labels]
        if len(set(ids)) != len(ids) or not all(0 <= i <= 255 for i in ids):
            raise ValueError(f"label ids must be unique and within 0..255, got {ids}")

    def by_name(self, name: str) -> Label:
        for lab in self.labels:
            if lab.name == name:
                return lab
        raise KeyError(name)

    def to_json(self) -> list[dict[str, Any]]:
        """The table as JSON rows ``{"id", "name", "color"}`` (run.json, agrisim's GLB extras)."""
        return [{"id": lab.id, "name": lab.name, "color": [int(c) for c in lab.color]} for lab in self.labels]

    @classmethod
    def from_json(cls, rows: list[dict[str, Any]]) -> LabelTable:
        """The table of :meth:`to_json`'s rows (KeyError, TypeError or ValueError if malformed)."""
        return cls([Label(int(r["id"]), str(r["name"]), tuple(int(c) for c in r["color"])) for r in rows])  # type: ignore[arg-type]

    def palette(self) -> np.ndarray:
        """256 x 3 uint8: colour of every label id (black for unused ids)."""
        out = np.zeros((256, 3), np.uint8)
        for lab in self.labels:
            out[lab.id] = lab.color
        return out


@dataclass
class Light:
    """A light: ``area`` lights are discs of ``radius`` facing ``direction`` (soft shadows);
    ``spot`` lights are points with a cone (``cone_deg`` half angle)."""

    name: str
    kind: Literal["area", "spot", "point"]
    position: np.ndarray
    direction: np.ndarray  # unit vector the light faces
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0  # radiant intensity scale, W/sr-like (renderer-relative)
    radius: float = 0.0  # disc radius of area lights, m
    cone_deg: float = 90.0  # half angle of the cone, degrees


#: The cylinder every plant must fit in at scale 1 to stay clear of the routine's cameras:
#: radius from the stem axis and height above the soil, m (the brief's is 0.28 x 0.40 m; the
#: species keep a centimetre to spare). Every plant source scales to it.
PLANT_FIT_RADIUS = 0.27
PLANT_FIT_HEIGHT = 0.39


@dataclass(frozen=True)
class BenchPlant:
    """One plant of a bench (``[bench]``): its name (``plant_01``...), what grew it (a species or
    a file) and from which seed, where its pot stands from the bench's centre (x, y, m), and
    which faces of the joined plant mesh are its own (``range(*faces)``). Its id in the
    ``plants/`` masks is its place in the bench's list plus one."""

    name: str
    plant: str
    seed: int
    xy: tuple[float, float]
    faces: tuple[int, int] = (0, 0)


@dataclass
class Plant:
    """A plant asset: its mesh in the plant frame and the label table its materials use.

    ``points``, when set, is what is drawn: the plant as a point cloud. Its ``mesh`` is then the
    surface the points were sampled from (``--as-points``; the ground truth of accuracy), or has
    no faces when the points are all there is (a scan read from a file).

    ``organs`` is True when the label table names several organs (``--labels organs``);
    ``--labels plant`` maps every non-zero id to 1. ``notes`` say how the plant was made and
    anything the user should know (e.g. that it was scaled down to fit the routine).
    """

    name: str
    mesh: Mesh
    labels: LabelTable
    organs: bool = False
    seed: int = 0
    notes: list[str] = field(default_factory=list)
    points: PointSet | None = None
    bench: list[BenchPlant] = field(default_factory=list)
    """The plants it joins, when it is a bench (:func:`agrisim.bench.join_plants`); else empty."""


@dataclass
class Scene:
    """Everything a renderer draws besides the arms: static meshes in world coordinates (room,
    stands, table, pot, clutter, the plant placed in its pot), the lights, the label table."""

    meshes: list[Mesh]
    lights: list[Light]
    labels: LabelTable
    plant: str = "plant"  # name of the plant's mesh in ``meshes``
    arms: dict[str, list[tuple[str, Mesh]]] = field(default_factory=dict)
    """The arms' visual meshes as a renderer drew them: robot -> (link, mesh in the link's
    frame). A run fills it from its renderer and saves it with the scene; a renderer given a
    scene with arms draws these instead of loading the cell's URDFs (``agrisim render``)."""
    points: PointSet | None = None
    """The plant drawn as points (world, labels of ``labels``); then no mesh is named ``plant``."""
    source: Mesh | None = None
    """The surface a point plant was sampled from (world; ``--as-points``), not drawn: the
    ground truth of accuracy. None for mesh plants and for scans."""
    bench: list[BenchPlant] = field(default_factory=list)
    """The bench's plants, each a range of the plant mesh's faces; empty for one plant."""

    def plant_surface(self) -> Mesh | None:
        """The plant's true surface in world coordinates: its drawn mesh, or the mesh its points
        were sampled from; None for a scanned point plant (its points are all there is)."""
        if self.points is not None:
            return self.source
        return self.mesh(self.plant)

    def mesh(self, name: str) -> Mesh:
        for m in self.meshes:
            if m.name == name:
                return m
        raise KeyError(name)
