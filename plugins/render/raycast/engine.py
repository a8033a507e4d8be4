"""The scene in Mitsuba's ray tracing, traced exactly on Dr.Jit arrays: Embree on the CPU
(``llvm``), OptiX on NVIDIA GPUs (``cuda``).

What Embree and OptiX do not know is written here, as Dr.Jit code that runs in the same kernels
as the ray casts: which surface a ray keeps (cut-out texels and culled back faces are passed,
in a Dr.Jit loop, up to ``max_layers`` surfaces), its material, texture coordinates and normal,
and whether a shadow ray is blocked (light falls through cut-out texels).

Geometry. The static scene (room, table, plant) is one triangle mesh; each arm link is a shape
group placed by an instance whose transform is the link's pose. Posing the arms per frame sets
those transforms and never touches the static mesh's acceleration structure: on the CPU the
static mesh and the arms are two Mitsuba scenes (Mitsuba's Embree rebuilds every shape group of
a scene whose instances move, so the arms' scene is rebuilt and the static one never); OptiX
traces one scene per kernel, so on the GPU the static mesh is a shape group of its own placed
once, beside the arms (only groups whose shapes change are rebuilt there). Faces are numbered
globally: the static mesh's first, then each link's; a hit's face is its instance's first face
plus the primitive index.

A point plant's spheres are another Mitsuba scene (``ellipsoids``, in a frame whose unit is
their radius: :mod:`.points`), traced in the same kernels on the CPU; the nearer hit wins.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import drjit as dr
import numpy as np

from agrisim.plugins.render.raycast.lights import SHADOW_TFAR
from agrisim.plugins.render.raycast.materials import MaterialArrays, MaterialTable
from agrisim.scene.model import Material, Mesh, Scene

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
        verts, faces = [], []
        n_faces = n_verts = 0
        self.has_instances = False
        self.plant_faces = (0, 0)  # global face range of the plant mesh (the first so named)
        for mesh in scene.meshes:
            if len(mesh.faces) == 0:
                continue
            plant = mesh.name == scene.plant and self.plant_faces == (0, 0)
            if plant:
                self.plant_faces = (n_faces, n_faces + len(mesh.faces))
            index = np.array([mats.add(m) for m in mesh.materials], np.int32)
            verts.append(mesh.vertices.astype(F32))
            faces.append(mesh.faces.astype(np.int64) + n_verts)
            face_mat.append(index[mesh.face_material])
            face_uv.append(mesh.uvs[mesh.faces] if mesh.uvs is not None else np.zeros((len(mesh.faces), 3, 2), F32))
            face_normal.append(_face_normals(mesh.vertices, mesh.faces))
            face_rgb.append(
                mesh.colors[mesh.faces] if mesh.colors is not None else np.ones((len(mesh.faces), 3, 3), F32)
            )
            if plant and mesh.face_instance is not None:
                self.has_instances = True
                face_inst.append(mesh.face_instance)
            else:
                face_inst.append(np.zeros(len(mesh.faces), np.uint16))
            face_slot.append(np.zeros(len(mesh.faces), np.uint32))
            n_faces += len(mesh.faces)
            n_verts += len(mesh.vertices)
        n_static = n_faces

        arm_shapes: dict[str, Any] = {}
        first_face: dict[str, int] = {"static": 0}  # instance id -> its first global face
        self.links: list[_Link] = []
        for a, (arm_name, link_meshes) in enumerate(arms.items()):
            for j, (link_name, mesh) in enumerate(link_meshes):
                if len(mesh.faces) == 0:
                    continue
                index = np.array([mats.add(m) for m in mesh.materials], np.int32)
                name = f"arm{a}_{j:02d}"
                arm_shapes[name + "_group"] = {
                    "type": "shapegroup",
                    "mesh": self._mesh(name, mesh.vertices.astype(F32), mesh.faces),
                }
                arm_shapes[name] = {
                    "type": "instance",
                    "shapegroup": {"type": "ref", "id": name + "_group"},
                    "to_world": mi.ScalarTransform4f(_PARKED),
                }
                first_face[name] = n_faces
                self.links.append(_Link(arm_name, link_name, name, len(self.links) + 1))
                face_mat.append(index[mesh.face_material])
                face_uv.append(np.zeros((len(mesh.faces), 3, 2), F32))
                face_normal.append(_face_normals(mesh.vertices, mesh.faces))  # link frame: turned per frame
                face_rgb.append(np.ones((len(mesh.faces), 3, 3), F32))
                face_inst.append(np.zeros(len(mesh.faces), np.uint16))
                face_slot.append(np.full(len(mesh.faces), len(self.links), np.uint32))
                n_faces += len(mesh.faces)
        mats.finish()
        self.mats = mats

        # Embree (llvm): the static mesh is a scene of its own, built once, and the arms another,
        # rebuilt when they move (Mitsuba's Embree rebuilds every shape group of a scene whose
        # instances move). OptiX (cuda) traces one scene per kernel: the static mesh is a shape
        # group placed once, beside the arms' instances (only the top level is rebuilt).
        self.combined = mi.variant().startswith("cuda")
        static = self._mesh("static", np.concatenate(verts), np.concatenate(faces)) if n_static else None
        self.layers: list[Any] = []
        arm_layer = None
        if self.combined:
            shapes = {"type": "scene", **arm_shapes}
            if static is not None:
                shapes["static_group"] = {"type": "shapegroup", "mesh": static}
                shapes["static"] = {"type": "instance", "shapegroup": {"type": "ref", "id": "static_group"}}
            if len(shapes) > 1:
                self.layers.append(mi.load_dict(shapes))
                arm_layer = self.layers[0]
        else:
            if static is not None:
                self.layers.append(mi.load_dict({"type": "scene", "static": static}))
            if arm_shapes:
                arm_layer = mi.load_dict({"type": "scene", **arm_shapes})
                self.layers.append(arm_layer)
        self.params = None
        if self.links:  # only the instances' transforms: the shape groups' own parameters never change
            self.params = mi.traverse(arm_layer)
            self.params.keep([f"{link.instance}.to_world" for link in self.links])
        # Instances are told apart by their Mitsuba registry ids (what a hit's ``instance``
        # holds; 0 for a hit on a shape placed directly: the static mesh's first face is 0).
        ids = {
            sh.id(): int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(sh))[0])
            for layer in self.layers
            for sh in layer.shapes()
        }
        ids = {name: i for name, i in ids.items() if name in first_face}
        face0 = np.zeros(max(ids.values(), default=0) + 1, np.uint32)
        for name, registry_id in ids.items():
            face0[registry_id] = first_face[name]
        self._inst_face0 = mi.UInt32(face0)

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
    def _mesh(self, name: str, vertices: np.ndarray, faces: np.ndarray) -> Any:
        mi = self.mi
        shape = mi.Mesh(name, len(vertices), len(faces), has_vertex_normals=False, has_vertex_texcoords=False)
        params = mi.traverse(shape)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, F32).ravel())
        params["faces"] = mi.UInt32(np.ascontiguousarray(faces, np.uint32).ravel())
        params.update()
        return shape

    # ------------------------------------------------------------------- posing
    def place_arms(self, link_poses: Mapping[str, Mapping[str, np.ndarray]]) -> None:
        """Pose the arms at ``link_poses`` (robot -> link -> world_T_link); arms not named there
        are left out. Only the instances' transforms change: the static scene's acceleration
        structure is not rebuilt."""
        if not self.links:
            return
        poses = []
        for link in self.links:
            lp = link_poses.get(link.arm)
            if lp is not None and link.link not in lp:
                raise KeyError(f"link_poses[{link.arm!r}] has no pose for link {link.link!r}")
            poses.append(_PARKED if lp is None else np.asarray(lp[link.link], np.float64))
        key = np.stack(poses).tobytes()
        if key == self._pose_key:
            return
        mi = self.mi
        rotation = np.tile(np.eye(3), (len(self.links) + 1, 1, 1))
        for link, T in zip(self.links, poses, strict=True):
            self.params[f"{link.instance}.to_world"] = mi.Transform4f(T)
            rotation[link.slot] = T[:3, :3]
        self.params.update()
        self._rotation = mi.Float(rotation.astype(F32).reshape(-1))
        self._pose_key = key

    # ------------------------------------------------------------ per-hit tables
    def intersect(self, ray: Any, active: Any, coherent: bool = False) -> tuple[Any, Any, Any]:
        """Nearest triangle along each ray, of the static scene and the arms: (Float t, inf for
        none; Int32 global face, -1 for none; Vector2f barycentrics)."""
        mi = self.mi
        n = dr.width(ray.o)
        t, face, b = dr.full(mi.Float, dr.inf, n), dr.full(mi.Int32, NO_FACE, n), dr.zeros(mi.Vector2f, n)
        for layer in self.layers:
            pi = layer.ray_intersect_preliminary(ray, coherent=coherent, active=active)
            hit = active & pi.is_valid() & (pi.t < t)
            face0 = dr.gather(mi.UInt32, self._inst_face0, dr.reinterpret_array(mi.UInt32, pi.instance), hit)
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
        """The surface each ray (origins ``o``, directions ``d``: Vector3f) keeps, walking past
        cut-out texels and culled back faces in one Dr.Jit loop; with ``raw`` also the first
        surface of any opacity that culling keeps (repopa's labels)."""
        mi = self.mi
        n = dr.width(o)
        # Traced along unit directions, in metres: Embree's coherent packets (primary rays are)
        # lost hits on rays of other lengths (9,000 pixels of one 1080p view saw past the pot).
        length = dr.norm(d)
        d = d / length
        eps = mi.Float(self.epsilon)
        walk = self.mats.cutting or self.mats.culling
        zero_i = dr.full(mi.Int32, NO_FACE, n)

        def body(layer, active, t_acc, t, face, b, raw_face, raw_b, raw_t):
            ray = mi.Ray3f((d * t_acc + o) if walk else o, d)
            th, f, bh = self.intersect(ray, active, coherent=True)
            valid = f >= 0
            if walk:
                passes, culled, _ = self._passes(valid, f, bh, d)
            else:
                passes, culled = mi.Bool(False), None
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
            return layer, go & (layer < self.max_layers), t_acc, t, face, b, raw_face, raw_b, raw_t

        inf = dr.full(mi.Float, dr.inf, n)
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
        )
        if walk:
            _, _, _, t, face, b, raw_face, raw_b, raw_t = dr.while_loop(
                state, lambda layer, active, *_: active, body, label="agrisim_walk"
            )
        else:
            _, _, _, t, face, b, raw_face, raw_b, raw_t = body(*state)
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
        for layer in self.layers:
            blocked |= layer.ray_test(segment(o, seg), active & ~blocked)
        if not self.mats.cutting:
            return blocked

        # Blocked, perhaps only by cut-out texels: walk along the segment surface by surface,
        # from just past each hit, still aiming at the same point of the light.
        def body(layer, active, o, seg, blocked):
            th, f, bh = self.intersect(segment(o, seg), active)
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

        state = (mi.UInt32(0), mi.Bool(blocked & active), mi.Point3f(o), mi.Vector3f(seg), mi.Bool(blocked))
        return dr.while_loop(state, lambda layer, active, *_: active, body, label="agrisim_shadow")[4]
