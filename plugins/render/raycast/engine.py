"""The scene in Mitsuba's ray tracing, traced exactly on Dr.Jit arrays: Embree on the CPU
(``llvm``), OptiX on NVIDIA GPUs (``cuda``).

What Embree and OptiX do not know is written here, as Dr.Jit code that runs in the same kernels
as the ray casts: which surface a ray keeps (cut-out texels and culled back faces are passed,
in a Dr.Jit loop, up to ``max_layers`` surfaces), its material, texture coordinates and normal,
and whether a shadow ray is blocked (light falls through cut-out texels).

Geometry. The static scene (room, table, plant) is triangle meshes; each arm link is a shape
group placed by an instance whose transform is the link's pose. Posing the arms never touches
the static meshes' acceleration structures: on the CPU the static meshes and the arms are
separate Mitsuba scenes, the arms' made anew at each pose from the links that the view's rays
can meet (:mod:`.culling`; Mitsuba's Embree builds every shape group of a scene, so a link left
out is a build and a traversal saved); shadow rays get a scene of their own when they can meet
other links. OptiX traces one scene per kernel, so on the GPU the static mesh is a shape group
of its own placed once, beside every link's instance, posed by their transforms (only groups
whose shapes change are rebuilt there).

On the CPU the static meshes are split by what a ray can pass: ``solid`` meshes (no material
with cut-out texels or culled back faces: the room, the table, the arms) are cast once, and the
walk past cut-out texels and culled faces casts only the ``walk`` meshes (the plant), short of
the solid hit. Each layer of the walk then traverses the plant's small BVH instead of the
whole lab's and the arms' two-level one (issue 44: on 8 lanes the walk was most of a view).
Faces are numbered globally: the solid static mesh's first, then the walked one's, then each
link's; a hit's face is its layer's first face (its instance's, for the arms) plus the
primitive index.

A point plant's spheres are another Mitsuba scene (``ellipsoids``, in a frame whose unit is
their radius: :mod:`.points`), traced in the same kernels on the CPU; the nearer hit wins.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import drjit as dr
import numpy as np

from agrisim.plugins.render.raycast.culling import box_corners
from agrisim.plugins.render.raycast.lights import SHADOW_TFAR
from agrisim.plugins.render.raycast.materials import MaterialArrays, MaterialTable
from agrisim.scene.model import Material, Mesh, Scene
from agrisim.scene.texturing import alpha_threshold

F32 = np.float32
#: a face index of no face (a miss)
NO_FACE = -1
#: where the instances of arms that a frame leaves out are parked: shrunk to nothing, far away
_PARKED = np.diag([1e-12, 1e-12, 1e-12, 1.0])
_PARKED[:3, 3] = 1e9


def _face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return (n / np.where(length > 0, length, 1.0)).astype(F32)


@dataclass
class _Link:
    arm: str
    link: str
    instance: str  # the instance's id in the Mitsuba scene
    slot: int  # row of its rotation in the per-frame table
    face0: int  # its first global face
    corners: np.ndarray  # (8, 3) corners of its box, in the link frame
    group: Any = None  # CPU: its shape group
    # CPU: the instance placing the group, built with the engine and moved from pose to pose. A
    # new instance each pose (or each link first seen) would be a new Shape in Dr.Jit's registry,
    # and every kernel that dispatches over Shapes (Mitsuba's path tracer in the same process,
    # whose exact pass this is) would compile anew at each view: 5 s a view at 96x54 on a Xeon
    placed: Any = None
    placed_params: Any = None


@dataclass
class _Layer:
    """One Mitsuba scene the rays are cast into."""

    scene: Any
    base: int  # global index of its directly placed mesh's first face (instances: their own)
    solid: bool  # no face of it passes a ray on: cast once, not walked


def passes_rays(material: Material) -> bool:
    """Can a ray go on past a face of ``material`` (cut-out texels, or culled back faces)?"""
    return alpha_threshold(material) > 0 or not material.double_sided


@dataclass
class Surface:
    """What a ray keeps (Dr.Jit arrays, one entry per ray): the first surface that is neither a
    cut-out texel nor a culled back face."""

    t: Any
    """Float: distance in units of the ray's direction from its origin; inf: none."""
    face: Any
    """Int32: global face index, -1 where no triangle is kept (a miss, or a sphere)."""
    b: Any
    """Vector2f: Embree's barycentrics (weights of the second and third corners)."""
    point: Any = None
    """Int32: the point plant's sphere kept (``face`` is then -1), -1: none; None without points."""
    raw_face: Any = None
    """Int32: with ``raw``, the first surface of any opacity (repopa's labels), -1: none."""
    raw_b: Any = None
    raw_t: Any = None
    """Float: t of that first surface (inf: none)."""
    raw_point: Any = None

    @property
    def hit(self) -> Any:
        """Bool: did the ray keep a surface (a triangle or a sphere)?"""
        return (self.face >= 0) if self.point is None else (self.face >= 0) | (self.point >= 0)


class Engine:
    """The static scene, the arms (posed by :meth:`place_arms`) and a point plant's spheres in
    Mitsuba, with every per-face and per-material table the exact pass reads as Dr.Jit arrays.

    ``arms``: robot -> (link, mesh in the link frame); empty: no arms. ``mi``: Mitsuba set to
    the variant to trace with (:func:`agrisim.plugins.render.mitsuba.variant.use_variant`).
    """

    def __init__(
        self,
        mi: Any,
        scene: Scene,
        arms: Mapping[str, list[tuple[str, Mesh]]],
        *,
        max_layers: int = 16,
        epsilon: float = 1e-4,
    ) -> None:
        self.mi = mi
        self.max_layers = int(max_layers)
        self.epsilon = float(epsilon)
        mats = MaterialTable()
        mats.add(Material("default"))  # index 0: what the face tables hold when there are no faces
        face_mat, face_uv, face_normal, face_inst, face_slot, face_rgb = [], [], [], [], [], []
        # (vertices, faces) of the solid static mesh and of the walked one, numbered in that order
        groups: dict[bool, tuple[list[np.ndarray], list[np.ndarray]]] = {False: ([], []), True: ([], [])}
        n_faces = 0
        self.has_instances = False
        self.has_plants = False  # face_inst holds plant << 16 | leaf instance (a bench)
        self.leaf_instances = True  # ... and the bench has leaf instances in the low bits
        self.plant_faces = (0, 0)  # global face range of the plant mesh (the first so named)
        meshes = [m for m in scene.meshes if len(m.faces)]
        plant_mesh = next((i for i, m in enumerate(meshes) if m.name == scene.plant), -1)
        walked = [any(passes_rays(m.materials[k]) for k in np.unique(m.face_material)) for m in meshes]
        order = [i for i in range(len(meshes)) if not walked[i]] + [i for i in range(len(meshes)) if walked[i]]
        for i in order:
            mesh, plant = meshes[i], i == plant_mesh
            if plant:
                self.plant_faces = (n_faces, n_faces + len(mesh.faces))
            index = np.array([mats.add(m) for m in mesh.materials], np.int32)
            verts, faces = groups[walked[i]]
            faces.append(mesh.faces.astype(np.int64) + sum(len(v) for v in verts))
            verts.append(mesh.vertices.astype(F32))
            face_mat.append(index[mesh.face_material])
            face_uv.append(mesh.uvs[mesh.faces] if mesh.uvs is not None else np.zeros((len(mesh.faces), 3, 2), F32))
            face_normal.append(_face_normals(mesh.vertices, mesh.faces))
            face_rgb.append(
                mesh.colors[mesh.faces] if mesh.colors is not None else np.ones((len(mesh.faces), 3, 3), F32)
            )
            if plant and scene.bench:  # a bench: each face's plant in the high 16 bits
                self.has_instances = self.has_plants = True
                self.leaf_instances = mesh.face_instance is not None
                owner = np.zeros(len(mesh.faces), np.uint32)
                for k, member in enumerate(scene.bench):
                    owner[slice(*member.faces)] = k + 1
                leaf = np.zeros(len(mesh.faces), np.uint32) if mesh.face_instance is None else mesh.face_instance
                face_inst.append(leaf.astype(np.uint32) | owner << 16)
            elif plant and mesh.face_instance is not None:
                self.has_instances = True
                face_inst.append(mesh.face_instance)
            else:
                face_inst.append(np.zeros(len(mesh.faces), np.uint16))
            face_slot.append(np.zeros(len(mesh.faces), np.uint32))
            n_faces += len(mesh.faces)
        n_solid = sum(len(f) for f in groups[False][1])

        arm_shapes: dict[str, Any] = {}  # OptiX: the arms' shape groups and instances, posed by parameters
        self.combined = mi.variant().startswith("cuda")
        self._arms_solid = True
        self.links: list[_Link] = []
        for a, (arm_name, link_meshes) in enumerate(arms.items()):
            for j, (link_name, mesh) in enumerate(link_meshes):
                if len(mesh.faces) == 0:
                    continue
                index = np.array([mats.add(m) for m in mesh.materials], np.int32)
                self._arms_solid &= not any(passes_rays(mesh.materials[k]) for k in np.unique(mesh.face_material))
                name = f"arm{a}_{j:02d}"
                group = {"type": "shapegroup", "mesh": self._mesh(name, mesh.vertices.astype(F32), mesh.faces)}
                link = _Link(arm_name, link_name, name, len(self.links) + 1, n_faces, box_corners(mesh.vertices))
                if self.combined:
                    arm_shapes[name + "_group"] = group
                    arm_shapes[name] = {
                        "type": "instance",
                        "shapegroup": {"type": "ref", "id": name + "_group"},
                        "to_world": mi.ScalarTransform4f(_PARKED),
                    }
                else:
                    link.group = mi.load_dict(group)
                    link.placed = mi.load_dict(
                        {"type": "instance", "shapegroup": link.group, "to_world": mi.ScalarTransform4f(_PARKED)}
                    )
                    link.placed.set_id(name)
                    link.placed_params = mi.traverse(link.placed)
                self.links.append(link)
                face_mat.append(index[mesh.face_material])
                face_uv.append(np.zeros((len(mesh.faces), 3, 2), F32))
                face_normal.append(_face_normals(mesh.vertices, mesh.faces))  # link frame: turned per frame
                face_rgb.append(np.ones((len(mesh.faces), 3, 3), F32))
                face_inst.append(np.zeros(len(mesh.faces), np.uint16))
                face_slot.append(np.full(len(mesh.faces), len(self.links), np.uint32))
                n_faces += len(mesh.faces)
        mats.finish()
        self.mats = mats

        # Embree (llvm): the solid static mesh and the walked one are scenes of their own, built
        # once; the arms are a scene built anew at each pose from the links' shape groups and the
        # links that the view's rays can meet (Mitsuba's Embree rebuilds every shape group of a
        # scene whose instances move, so a link left out is a build saved). OptiX (cuda) traces
        # one scene per kernel: the static mesh is a shape group placed once, beside the arms'
        # instances (only the top level is rebuilt), and every layer of the walk casts it all.
        self._static: list[_Layer] = []
        self._seen: _Layer | None = None  # the arms for the camera's rays
        self._shadow: _Layer | None = None  # the arms for shadow rays (built when first cast)
        self._shadow_spec: tuple[list[np.ndarray | None], np.ndarray] | None = None
        self.params = None
        if self.combined:
            shapes = {"type": "scene", **arm_shapes}
            if groups[False][1] or groups[True][1]:
                v, f = self._concat(groups[False], groups[True])
                shapes["static_group"] = {"type": "shapegroup", "mesh": self._mesh("static", v, f)}
                shapes["static"] = {"type": "instance", "shapegroup": {"type": "ref", "id": "static_group"}}
            if len(shapes) > 1:
                self._static.append(_Layer(mi.load_dict(shapes), 0, solid=False))
            if self.links:  # only the instances' transforms: the shape groups' own parameters never change
                self.params = mi.traverse(self._static[0].scene)
                self.params.keep([f"{link.instance}.to_world" for link in self.links])
        else:
            for walk, base in ((False, 0), (True, n_solid)):
                if groups[walk][1]:
                    mesh = self._mesh("static", *self._concat(groups[walk]))
                    self._static.append(_Layer(mi.load_dict({"type": "scene", "static": mesh}), base, solid=not walk))
        self._index_instances()

        cat = np.concatenate
        UInt32, Float = mi.UInt32, mi.Float
        self.face_mat = UInt32(cat(face_mat).astype(np.uint32) if face_mat else np.zeros(1, np.uint32))
        uv = (cat(face_uv) if face_uv else np.zeros((1, 3, 2), F32)).astype(F32).reshape(-1)
        self.face_uv = Float(uv)
        self.face_normal = Float((cat(face_normal) if face_normal else np.zeros((1, 3), F32)).reshape(-1))
        self.face_inst = UInt32((cat(face_inst) if face_inst else np.zeros(1, np.uint16)).astype(np.uint32))
        self.face_slot = UInt32(cat(face_slot) if face_slot else np.zeros(1, np.uint32))
        # vertex colours only where a mesh has them: without, colour() is white and costs nothing
        self.has_colors = any(m.colors is not None for m in scene.meshes if len(m.faces))
        self.face_rgb = Float(cat(face_rgb).astype(F32).reshape(-1)) if self.has_colors else None
        self._rotation = Float(np.tile(np.eye(3, dtype=F32).reshape(-1), len(self.links) + 1))
        self._pose_key: bytes | None = None
        self.m = MaterialArrays(mi, mats)

    # ------------------------------------------------------------------ building
    @staticmethod
    def _concat(*groups: tuple[list[np.ndarray], list[np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
        """One (vertices, faces) of meshes listed as (vertex arrays, face arrays indexing their
        group's concatenated vertices), in the order given."""
        verts, faces, n = [], [], 0
        for vs, fs in groups:
            verts += vs
            faces += [f + n for f in fs]
            n += sum(len(v) for v in vs)
        return np.concatenate(verts), np.concatenate(faces)

    def _mesh(self, name: str, vertices: np.ndarray, faces: np.ndarray) -> Any:
        mi = self.mi
        shape = mi.Mesh(name, len(vertices), len(faces), has_vertex_normals=False, has_vertex_texcoords=False)
        params = mi.traverse(shape)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, F32).ravel())
        params["faces"] = mi.UInt32(np.ascontiguousarray(faces, np.uint32).ravel())
        params.update()
        return shape

    def _index_instances(self) -> None:
        """The table from a hit's instance (its Mitsuba registry id: a hit's ``instance``; 0 for
        a shape placed directly, whose layer gives its first face) to its first global face."""
        mi = self.mi
        face0 = {link.instance: link.face0 for link in self.links} | {"static": 0}
        ids = {
            int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(sh))[0]): face0[sh.id()]
            for layer in [*self._static, self._seen, self._shadow]
            if layer is not None
            for sh in layer.scene.shapes()
            if sh.id() in face0
        }
        table = np.zeros(max(ids, default=0) + 1, np.uint32)
        for registry_id, first in ids.items():
            table[registry_id] = first
        self._inst_face0 = mi.UInt32(table)

    @property
    def layers(self) -> list[_Layer]:
        """The scenes the camera's rays are cast into: the static ones, then the posed arms."""
        return self._static + ([self._seen] if self._seen is not None and self._seen not in self._static else [])

    def _shadow_layers(self) -> list[_Layer]:
        if self._shadow is None and self._shadow_spec is not None:
            self._shadow = self._arm_layer(*self._shadow_spec)
            self._shadow_spec = None
            self._index_instances()
        arms = self._shadow if self._shadow is not None and self._shadow not in self._static else None
        return self._static + ([arms] if arms is not None else [])

    def _arm_layer(self, poses: list[np.ndarray | None], keep: np.ndarray) -> _Layer | None:
        """A scene of the links posed at ``poses`` (None: left out) that ``keep`` keeps."""
        shapes: dict[str, Any] = {"type": "scene"}
        for link, T, kept in zip(self.links, poses, keep, strict=True):
            if T is not None and kept:
                shapes[link.instance + "_group"] = link.group  # (only a scene's own groups are built)
                shapes[link.instance] = self._placed(link, T)
        return _Layer(self.mi.load_dict(shapes), 0, solid=self._arms_solid) if len(shapes) > 1 else None

    def _placed(self, link: _Link, T: np.ndarray) -> Any:
        """``link``'s instance (CPU), moved to ``T``."""
        link.placed_params["to_world"] = self.mi.ScalarTransform4f(T)
        link.placed_params.update()
        return link.placed

    # ------------------------------------------------------------------- posing
    def link_poses(self, link_poses: Mapping[str, Mapping[str, np.ndarray]]) -> list[np.ndarray | None]:
        """world_T_link of each link in :attr:`links`' order, None for an arm not in
        ``link_poses`` (robot -> link -> world_T_link)."""
        poses: list[np.ndarray | None] = []
        for link in self.links:
            lp = link_poses.get(link.arm)
            if lp is not None and link.link not in lp:
                raise KeyError(f"link_poses[{link.arm!r}] has no pose for link {link.link!r}")
            poses.append(None if lp is None else np.asarray(lp[link.link], np.float64))
        return poses

    def place_arms(
        self,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
        seen: np.ndarray | None = None,
        shading: np.ndarray | None = None,
    ) -> None:
        """Pose the arms at ``link_poses`` (robot -> link -> world_T_link); arms not named there
        are left out. ``seen`` and ``shading`` (bool per link of :attr:`links`; default all)
        name the links that the camera's rays and the shadow rays can meet (:mod:`.culling`);
        on the CPU only those are built and cast (OptiX casts all). The static scenes'
        acceleration structures are not rebuilt."""
        if not self.links:
            return
        poses = self.link_poses(link_poses)
        every = np.ones(len(self.links), bool)
        seen = every if seen is None else np.asarray(seen, bool)
        shading = every if shading is None else np.asarray(shading, bool)
        parked = [_PARKED if T is None else T for T in poses]
        key = np.stack(parked).tobytes() + seen.tobytes() + shading.tobytes()
        if key == self._pose_key:
            return
        mi = self.mi
        rotation = np.tile(np.eye(3), (len(self.links) + 1, 1, 1))
        for link, T in zip(self.links, parked, strict=True):
            rotation[link.slot] = T[:3, :3]
        if self.combined:
            for link, T in zip(self.links, parked, strict=True):
                self.params[f"{link.instance}.to_world"] = mi.Transform4f(T)
            self.params.update()
        else:
            self._seen = self._arm_layer(poses, seen)
            same = bool((seen == shading).all())
            self._shadow = self._seen if same else None
            self._shadow_spec = None if same else (poses, shading)
            self._index_instances()
        self._rotation = mi.Float(rotation.astype(F32).reshape(-1))
        self._pose_key = key

    # ------------------------------------------------------------ per-hit tables
    def intersect(
        self, ray: Any, active: Any, layers: list[_Layer] | None = None, coherent: bool = False
    ) -> tuple[Any, Any, Any]:
        """Nearest triangle along each ray, of ``layers`` (default: all, the static scene and
        the arms): (Float t, inf for none; Int32 global face, -1 for none; Vector2f
        barycentrics)."""
        mi = self.mi
        n = dr.width(ray.o)
        t, face, b = dr.full(mi.Float, dr.inf, n), dr.full(mi.Int32, NO_FACE, n), dr.zeros(mi.Vector2f, n)
        for layer in self.layers if layers is None else layers:
            pi = layer.scene.ray_intersect_preliminary(ray, coherent=coherent, active=active)
            hit = active & pi.is_valid() & (pi.t < t)
            face0 = dr.gather(mi.UInt32, self._inst_face0, dr.reinterpret_array(mi.UInt32, pi.instance), hit)
            if layer.base:
                face0 += layer.base
            t = dr.select(hit, pi.t, t)
            face = dr.select(hit, mi.Int32(face0 + pi.prim_index), face)
            b = dr.select(hit, pi.prim_uv, b)
        return t, face, b

    def uv(self, face: Any, b: Any, active: Any = True) -> Any:
        """Vector2f texture coordinates at barycentrics ``b`` of ``face``: ``w0 uv0 + w1 uv1 +
        w2 uv2`` with ``w0 = 1 - w1 - w2``, in that order (as the core's interpolate_uv)."""
        mi = self.mi
        f = mi.UInt32(dr.maximum(face, 0)) * 6
        c = [dr.gather(mi.Float, self.face_uv, f + k, active) for k in range(6)]
        w1, w2 = b.x, b.y
        w0 = (1.0 - w1) - w2
        return mi.Vector2f((w0 * c[0] + w1 * c[2]) + w2 * c[4], (w0 * c[1] + w1 * c[3]) + w2 * c[5])

    def color(self, face: Any, b: Any, active: Any = True) -> Any:
        """Color3f vertex colour at barycentrics ``b`` of ``face`` (white without any), weighted
        as :meth:`uv` weights texture coordinates."""
        mi = self.mi
        if self.face_rgb is None:
            return mi.Color3f(1.0)
        f = mi.UInt32(dr.maximum(face, 0)) * 9
        c = [dr.gather(mi.Float, self.face_rgb, f + k, active) for k in range(9)]
        w1, w2 = b.x, b.y
        w0 = (1.0 - w1) - w2
        return mi.Color3f(*((w0 * c[k] + w1 * c[3 + k]) + w2 * c[6 + k] for k in range(3)))

    def material(self, face: Any, active: Any = True) -> Any:
        """UInt32 material index of ``face`` (0 where it is -1)."""
        return dr.gather(self.mi.UInt32, self.face_mat, self.mi.UInt32(dr.maximum(face, 0)), active)

    def normal(self, face: Any, active: Any = True) -> Any:
        """Vector3f unit world normal of ``face`` (arms' turned by their link's pose)."""
        mi = self.mi
        f = mi.UInt32(dr.maximum(face, 0))
        n = [dr.gather(mi.Float, self.face_normal, f * 3 + k, active) for k in range(3)]
        slot = dr.gather(mi.UInt32, self.face_slot, f, active) * 9
        r = [dr.gather(mi.Float, self._rotation, slot + k, active) for k in range(9)]
        return mi.Vector3f(
            (r[0] * n[0] + r[1] * n[1]) + r[2] * n[2],
            (r[3] * n[0] + r[4] * n[1]) + r[5] * n[2],
            (r[6] * n[0] + r[7] * n[1]) + r[8] * n[2],
        )

    def _passes(self, valid: Any, face: Any, b: Any, d: Any) -> tuple[Any, Any, Any]:
        """(passes, culled, uv) of hits: does the ray go on past its hit (a cut-out texel or a
        culled back face)? ``culled`` is None when no material is single-sided."""
        mi, mats = self.mi, self.mats
        mat = self.material(face, valid)
        special = valid & dr.gather(mi.Bool, self.m.special, mat, valid)
        uv = self.uv(face, b, valid)
        passes = special & ~self.m.opaque(uv, mat, special)
        culled = None
        if mats.culling:
            n = self.normal(face, special)
            single = ~dr.gather(mi.Bool, self.m.double_sided, mat, special)
            culled = special & single & (dr.dot(n, d) > 0)
            passes |= culled
        return passes, culled, uv

    # ------------------------------------------------------------------- tracing
    def trace(self, o: Any, d: Any, raw: bool = False) -> Surface:
        """The surface each ray (origins ``o``, directions ``d``: Vector3f) keeps: the nearest
        solid hit, unless a walked surface before it is kept first; the walk past cut-out texels
        and culled back faces is one Dr.Jit loop. With ``raw`` also the first surface of any
        opacity that culling keeps (repopa's labels)."""
        mi = self.mi
        n = dr.width(o)
        # Traced along unit directions, in metres: Embree's coherent packets (primary rays are)
        # lost hits on rays of other lengths (9,000 pixels of one 1080p view saw past the pot).
        length = dr.norm(d)
        d = d / length
        eps = mi.Float(self.epsilon)
        # solid surfaces: one cast; the walk stops short of them (t_solid: inf where none)
        layers = self.layers
        solid, walked = [x for x in layers if x.solid], [x for x in layers if not x.solid]
        t_solid, f_solid, b_solid = self.intersect(mi.Ray3f(o, d), dr.full(mi.Bool, True, n), solid, coherent=True)
        zero_i = dr.full(mi.Int32, NO_FACE, n)
        inf = dr.full(mi.Float, dr.inf, n)

        def body(layer, active, t_acc, t, face, b, raw_face, raw_b, raw_t, gave_up):
            ray = mi.Ray3f(d * t_acc + o, d)
            ray.maxt = dr.minimum(t_solid - t_acc, dr.largest(mi.Float))
            th, f, bh = self.intersect(ray, active, walked, coherent=True)
            valid = f >= 0
            passes, culled, _ = self._passes(valid, f, bh, d)
            if raw:
                first = valid & (raw_face < 0)
                if culled is not None:
                    first &= ~culled
                raw_face = dr.select(first, f, raw_face)
                raw_b = dr.select(first, bh, raw_b)
                raw_t = dr.select(first, t_acc + th, raw_t)
            stop = valid & ~passes
            t = dr.select(stop, t_acc + th, t)
            face = dr.select(stop, f, face)
            b = dr.select(stop, bh, b)
            go = valid & passes
            t_acc = dr.select(go, (t_acc + th) + eps, t_acc)
            layer += 1
            gave_up = go & (layer >= self.max_layers)  # still passing surfaces: keeps none, as before
            return layer, go & ~gave_up, t_acc, t, face, b, raw_face, raw_b, raw_t, gave_up

        state = (
            mi.UInt32(0),
            dr.full(mi.Bool, True, n),
            dr.zeros(mi.Float, n),
            inf,
            zero_i,
            dr.zeros(mi.Vector2f, n),
            dr.copy(zero_i),
            dr.zeros(mi.Vector2f, n),
            dr.copy(inf),
            dr.full(mi.Bool, False, n),
        )
        if walked:
            _, _, _, t, face, b, raw_face, raw_b, raw_t, gave_up = dr.while_loop(
                state, lambda layer, active, *_: active, body, label="agrisim_walk"
            )
            # no walked surface kept, and the walk ended short of max_layers: the solid one (if any)
            solid = (face < 0) & ~gave_up
            t, face, b = dr.select(solid, t_solid, t), dr.select(solid, f_solid, face), dr.select(solid, b_solid, b)
            if raw:
                solid = (raw_face < 0) & ~gave_up
                raw_t = dr.select(solid, t_solid, raw_t)
                raw_face = dr.select(solid, f_solid, raw_face)
                raw_b = dr.select(solid, b_solid, raw_b)
        else:
            t, face, b, raw_t, raw_face, raw_b = t_solid, f_solid, b_solid, t_solid, f_solid, b_solid
        t = t / length  # back to units of the rays' own directions
        if not raw:
            return Surface(t, face, b)
        return Surface(t, face, b, raw_face=raw_face, raw_b=raw_b, raw_t=raw_t / length)

    def occluded(self, o: Any, seg: Any, active: Any = True) -> Any:
        """Bool: is each shadow ray (origin ``o``, segment ``seg`` to its light) blocked before
        ``SHADOW_TFAR`` of the segment? Cut-out texels let light through."""
        mi = self.mi

        def segment(o: Any, seg: Any) -> Any:
            ray = mi.Ray3f(o, seg)
            ray.maxt = mi.Float(SHADOW_TFAR)  # (Ray3f's third argument is the time, not maxt)
            return ray

        blocked = mi.Bool(False)
        layers = self._shadow_layers()
        solid, walked = [x for x in layers if x.solid], [x for x in layers if not x.solid]
        for layer in solid:
            blocked |= layer.scene.ray_test(segment(o, seg), active & ~blocked)
        if not walked:
            return blocked
        walk = mi.Bool(False)
        for layer in walked:
            walk |= layer.scene.ray_test(segment(o, seg), active & ~blocked & ~walk)
        if not self.mats.cutting:
            return blocked | walk

        # Blocked by the walked surfaces alone, perhaps only by cut-out texels: walk along the
        # segment surface by surface, from just past each hit, still aiming at the same point of
        # the light.
        def body(layer, active, o, seg, blocked):
            th, f, bh = self.intersect(segment(o, seg), active, walked)
            valid = f >= 0
            mat = self.material(f, valid)
            cut = valid & dr.gather(mi.Bool, self.m.cuts, mat, valid)
            cut &= ~self.m.opaque(self.uv(f, bh, cut), mat, cut)
            blocked = dr.select(active, valid & ~cut, blocked)
            step = dr.minimum(th + mi.Float(self.epsilon) / dr.norm(seg), 1.0)
            o = dr.select(cut, seg * step + o, o)
            seg = dr.select(cut, seg * (1.0 - step), seg)
            layer += 1
            still = cut & (layer < self.max_layers)
            blocked |= cut & ~still  # still among layers of cut-out cards after max_layers: shadowed
            return layer, still, o, seg, blocked

        state = (mi.UInt32(0), mi.Bool(walk), mi.Point3f(o), mi.Vector3f(seg), mi.Bool(walk))
        return blocked | dr.while_loop(state, lambda layer, active, *_: active, body, label="agrisim_shadow")[4]
