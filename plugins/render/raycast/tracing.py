"""Exact ray tracing of the scene for the raycast renderer (Open3D's Embree): the first kept
surface per ray through cut-out texels and culled back faces, labels and leaf instances, and
shadow rays; arms posed per frame."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast import kernels
from agrisim.plugins.render.raycast.arm_meshes import arm_link_meshes
from agrisim.plugins.render.raycast.lights import SHADOW_TFAR
from agrisim.plugins.render.raycast.materials import MaterialTable
from agrisim.plugins.render.raycast.points import PointTracer
from agrisim.scene.camera import CameraModel
from agrisim.scene.cell import Cell
from agrisim.scene.model import Material, Mesh, Scene
from agrisim.util.native_output import native_output_silenced

with native_output_silenced():
    import open3d as o3d

F32 = np.float32
INVALID = np.uint32(0xFFFFFFFF)  # Open3D's geometry/primitive id of a miss


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return (n / np.where(length > 0, length, 1.0)).astype(F32)


def _tensor(a: np.ndarray) -> o3d.core.Tensor:
    return o3d.core.Tensor.from_numpy(np.ascontiguousarray(a))


def _offsets(by_id: dict[int, int]) -> np.ndarray:
    out = np.zeros(max(by_id, default=-1) + 1, np.int64)
    for gid, off in by_id.items():
        out[gid] = off
    return out


def label_map(labels: str) -> np.ndarray:
    """Label id -> the id written (uint8, 256): every id as it is for ``labels="organs"``, else
    every non-zero id to 1 (the plant)."""
    ids = np.arange(256)
    return ids.astype(np.uint8) if labels == "organs" else (ids > 0).astype(np.uint8)


@lru_cache(maxsize=8)
def _slopes(width: int, height: int, fx: float, fy: float, cx: float, cy: float) -> tuple[np.ndarray, np.ndarray]:
    x = (np.arange(width, dtype=np.float64) - cx) / fx
    y = (np.arange(height, dtype=np.float64) - cy) / fy
    x.flags.writeable = y.flags.writeable = False  # shared by every caller of the cache
    return x, y


def pixel_slopes(camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame ray slopes of the pixel centres: x of each column, y of each row
    (``K^-1 [u, v, 1] = (x[u], y[v], 1)``)."""
    return _slopes(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy)


def camera_rays(x: np.ndarray, y: np.ndarray, T: np.ndarray, near: float) -> np.ndarray:
    """Rays (len(y) * len(x) x 6 float32, row-major) through camera-frame points (x, y, 1) of the
    camera at ``T`` (world_T_camera, OpenCV), from the near plane, with directions of unit camera
    z (so a hit's t is its planar depth less ``near``)."""
    R, c = T[:3, :3], T[:3, 3]
    rays = np.empty((len(y), len(x), 6), F32)
    d = np.empty((len(y), len(x)), F32)
    for j in range(3):  # component by component: long inner loops, one strided write each
        np.add((x * R[j, 0]).astype(F32)[None, :], (y * R[j, 1] + R[j, 2]).astype(F32)[:, None], out=d)
        rays[..., 3 + j] = d
        d *= F32(near)
        d += F32(c[j])
        rays[..., j] = d
    return rays.reshape(-1, 6)


@dataclass
class _Traceable:
    """One Embree scene, the global index of the first face of each of its geometries, and
    whether any of its triangles can be cut out by opacity."""

    scene: o3d.t.geometry.RaycastingScene
    offset: np.ndarray  # geometry id -> first global face
    cuts: bool


@dataclass
class _ArmLink:
    link: str
    vertices: np.ndarray  # (n, 3) float64, link frame
    normals: np.ndarray  # (m, 3) float64, link frame
    v0: int  # first vertex in the arm's vertex array
    f0: int  # first face in the arm's face array


@dataclass
class _Arm:
    name: str
    links: list[_ArmLink]
    faces: o3d.core.Tensor  # uint32, arm-local vertex indices
    n_vertices: int
    face0: int  # first face of this arm in the renderer's global face arrays


@dataclass
class Hits:
    """Per ray: the surface kept (opaque, facing), and for repopa the first surface of any
    opacity. ``mat`` and ``uv`` are valid where ``face >= 0`` (uv matters where the material is
    textured)."""

    t: np.ndarray  # (K,) float32 distance in ray-direction units from the rays' origins; inf: miss
    face: np.ndarray  # (K,) int64 global face index, -1: miss
    bary: np.ndarray  # (K, 2) float32 Open3D/Embree barycentrics
    mat: np.ndarray  # (K,) material index
    uv: np.ndarray  # (K, 2) float32 texture coordinates
    raw_face: np.ndarray | None = None
    raw_bary: np.ndarray | None = None
    point: np.ndarray | None = None
    """(K,) int64 index of the point plant's sphere hit (``face`` is then -1), -1: none; None
    when the scene has no point plant."""
    raw_t: np.ndarray | None = None
    """t of repopa's first surface (kept when a point plant's spheres may be nearer)."""
    raw_point: np.ndarray | None = None
    """repopa's first surface when it is a sphere (``raw_face`` is then -1)."""

    @property
    def hit(self) -> np.ndarray:
        """Did each ray hit anything (a triangle or a sphere)?"""
        return self.face >= 0 if self.point is None else (self.face >= 0) | (self.point >= 0)


class SceneTracer:
    """The scene and the posed arms in Embree, traced exactly: the first surface along each ray
    that opacity and back-face culling keep, its material, UV, label and leaf instance, and
    shadow rays through cut-out texels. Renderers share it for labels and depth (one exact
    pass); shading is theirs.

    The arms are ``arms`` (robot -> (link, mesh in the link frame)) when given, else the visual
    meshes of ``cell``'s URDFs; neither: no arms (``--hide-robots``).
    """

    def __init__(
        self,
        scene: Scene,
        cell: Cell | None,
        options: RaycastOptions,
        arms: Mapping[str, list[tuple[str, Mesh]]] | None = None,
    ) -> None:
        self.options = options
        self.threads = options.threads
        mats = MaterialTable()
        mats.add(Material("default"))  # index 0: what the face arrays hold when there are no faces
        face_mat, face_uv, face_normal, face_inst = [], [], [], []
        static = o3d.t.geometry.RaycastingScene(nthreads=self.threads)
        geom_offset: dict[int, int] = {}
        self._static_geometry: list[tuple[o3d.core.Tensor, o3d.core.Tensor, int]] = []
        n_faces = 0
        self.has_instances = False
        self.plant_faces = (0, 0)  # global face range of the plant mesh (the first so named)
        for mesh in scene.meshes:
            if len(mesh.faces) == 0:
                continue
            plant = mesh.name == scene.plant and self.plant_faces == (0, 0)
            if plant:
                self.plant_faces = (n_faces, n_faces + len(mesh.faces))
            index = np.array([mats.add(m) for m in mesh.materials], np.int32)
            geometry = (_tensor(mesh.vertices.astype(F32)), _tensor(mesh.faces.astype(np.uint32)), n_faces)
            self._static_geometry.append(geometry)
            geom_offset[int(static.add_triangles(geometry[0], geometry[1]))] = n_faces
            face_mat.append(index[mesh.face_material])
            face_uv.append(mesh.uvs[mesh.faces] if mesh.uvs is not None else np.zeros((len(mesh.faces), 3, 2), F32))
            face_normal.append(_face_normals(mesh.vertices, mesh.faces))
            if plant and mesh.face_instance is not None:
                self.has_instances = True
                face_inst.append(mesh.face_instance)
            else:
                face_inst.append(np.zeros(len(mesh.faces), np.uint16))
            n_faces += len(mesh.faces)
        self.n_static = n_faces

        self.arms: list[_Arm] = []
        if arms is None and cell is not None:
            arms = {a.name: [(lm.link, lm.mesh) for lm in arm_link_meshes(a.urdf, options.arm_triangles)] for a in cell.arms}
        if arms:
            for arm_name, link_meshes in arms.items():
                links, faces, nv, f0 = [], [], 0, n_faces
                for link_name, mesh in link_meshes:
                    index = np.array([mats.add(m) for m in mesh.materials], np.int32)
                    links.append(
                        _ArmLink(link_name, mesh.vertices, _face_normals(mesh.vertices, mesh.faces), nv, n_faces - f0)
                    )
                    faces.append(mesh.faces + nv)
                    face_mat.append(index[mesh.face_material])
                    face_uv.append(np.zeros((len(mesh.faces), 3, 2), F32))
                    face_normal.append(np.zeros((len(mesh.faces), 3), F32))  # posed per frame
                    face_inst.append(np.zeros(len(mesh.faces), np.uint16))
                    nv += len(mesh.vertices)
                    n_faces += len(mesh.faces)
                if links:
                    self.arms.append(_Arm(arm_name, links, _tensor(np.concatenate(faces).astype(np.uint32)), nv, f0))
        mats.finish()
        self.mats = mats
        cat = np.concatenate
        self.face_mat = (cat(face_mat) if face_mat else np.zeros(1)).astype(np.intp)  # index arrays: no casts in take
        self.face_uv = (cat(face_uv) if face_uv else np.zeros((1, 3, 2), F32)).reshape(-1, 6)
        # (3, faces): the shading code works on coordinates as rows (see LightTable.weights)
        self.face_normal = np.ascontiguousarray((cat(face_normal) if face_normal else np.zeros((1, 3), F32)).T)
        self.face_inst = cat(face_inst) if face_inst else np.zeros(1, np.uint16)
        self._static_scene = _Traceable(static, _offsets(geom_offset), mats.cutting) if self.n_static else None
        self._scenes: list[_Traceable] = [self._static_scene] if self._static_scene else []
        self._arm_key: bytes | None = None
        self.points: PointTracer | None = None
        if scene.points is not None and len(scene.points):
            self.points = PointTracer(scene.points)
            self.has_instances |= scene.points.instances is not None

    def place_arms(self, link_poses: Mapping[str, Mapping[str, np.ndarray]]) -> None:
        """Pose the arms named in ``link_poses`` (rebuilding only when the poses change)."""
        arms = [a for a in self.arms if a.name in link_poses]
        if not arms:
            self._scenes = [self._static_scene] if self._static_scene else []
            self._arm_key = None
            return
        poses = []
        for arm in arms:
            lp = link_poses[arm.name]
            for link in arm.links:
                if link.link not in lp:
                    raise KeyError(f"link_poses[{arm.name!r}] has no pose for link {link.link!r}")
                poses.append(np.asarray(lp[link.link], np.float64))
        key = "|".join(a.name for a in arms).encode() + np.stack(poses).tobytes()
        if key == self._arm_key:
            return
        merge = 0 < self.n_static <= self.options.merge_limit
        scene = o3d.t.geometry.RaycastingScene(nthreads=self.threads)
        offsets: dict[int, int] = {}
        if merge:
            for vertices, faces, offset in self._static_geometry:
                offsets[int(scene.add_triangles(vertices, faces))] = offset
        k = 0
        for arm in arms:
            verts = np.empty((arm.n_vertices, 3), F32)
            for link in arm.links:
                R, t = poses[k][:3, :3], poses[k][:3, 3]
                k += 1
                # einsum, not @: OpenBLAS's spinning threads would slow Embree's down
                verts[link.v0 : link.v0 + len(link.vertices)] = np.einsum("ij,kj->ik", link.vertices, R) + t
                f = arm.face0 + link.f0
                self.face_normal[:, f : f + len(link.normals)] = np.einsum("kj,ij->ki", R, link.normals)
            offsets[int(scene.add_triangles(_tensor(verts), arm.faces))] = arm.face0
        if merge:
            self._scenes = [_Traceable(scene, _offsets(offsets), self.mats.cutting)]
        else:
            posed = _Traceable(scene, _offsets(offsets), False)
            self._scenes = [self._static_scene, posed] if self._static_scene else [posed]
        self._arm_key = key

    def _cast_rays(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest hit of each ray (K x 6) over the scenes: (t, global face or -1, barycentrics)."""
        tensor = _tensor(rays)
        t = face = bary = None
        for sc in self._scenes:
            r = sc.scene.cast_rays(tensor, nthreads=self.threads)
            tt = r["t_hit"].numpy()
            g = r["geometry_ids"].numpy()
            if t is None:
                t, bary = tt, r["primitive_uvs"].numpy()
                face = np.take(sc.offset, g, mode="clip")  # (misses' INVALID ids clip: fixed below)
                face += r["primitive_ids"].numpy()
                miss = g == INVALID
                if miss.any():
                    face[miss] = -1
                continue
            nearer = np.flatnonzero(tt < t)
            if len(nearer):
                t[nearer] = tt[nearer]
                face[nearer] = np.take(sc.offset, g[nearer]) + r["primitive_ids"].numpy()[nearer]
                bary[nearer] = r["primitive_uvs"].numpy()[nearer]
        if t is None:
            k = len(rays)
            return np.full(k, np.inf, F32), np.full(k, -1, np.int64), np.zeros((k, 2), F32)
        return t, face, bary

    def _uv(self, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """UVs at hits: the arithmetic of agrisim.scene.texturing.interpolate_uv, operation for
        operation in float32 (so the same texels), on pre-gathered corner UVs."""
        uv = np.empty((len(face), 2), F32)
        kernels.interpolate_uv(face, bary, self.face_uv, uv)
        return uv

    def surface(self, face: np.ndarray, bary: np.ndarray):  # noqa: ANN202
        """(material, uv) of hits (``face`` >= 0; entries of misses are meaningless).

        UVs are interpolated on every hit, textured or not: nearly all hits need them, and
        picking the others out would cost more than it saves (untextured materials read 1 x 1
        textures, whatever the UV)."""
        return np.take(self.face_mat, face), self._uv(face, bary)

    def _passes(self, face, mat, uv, d, valid=None):  # noqa: ANN001, ANN202
        """(passes, culled): does each ray go on past its hit (a cut-out texel or a culled back
        face)? ``culled`` is None when no material is single-sided."""
        mats = self.mats
        special = np.take(mats.special, mat)
        if valid is not None:
            special &= valid
        sel = np.flatnonzero(special)
        passes = np.zeros(len(face), bool)
        culled = np.zeros(len(face), bool) if mats.culling else None
        if len(sel):
            m = mat[sel]
            p = ~mats.opaque(np.take(uv, sel, axis=0), m)
            if mats.culling:
                facing = _dot(np.take(self.face_normal, face[sel], axis=1).T, np.take(d, sel, axis=0))
                back = ~np.take(mats.double_sided, m) & (facing > 0)
                culled[sel] = back
                p |= back
            passes[sel] = p
        return passes, culled

    def trace(self, rays: np.ndarray, raw: bool) -> Hits:
        """First surface along each ray (K x 6: origin, direction) that is neither a cut-out texel
        nor a culled back face; with ``raw`` also the first of any opacity (repopa's labels).
        A point plant's spheres (opaque) win where they are nearer."""
        out = self._trace_triangles(rays, raw)
        if self.points is None:
            return out
        raw_t = out.raw_t if raw else None
        t, index = self.points.cast(rays)
        out.point = np.full(len(rays), -1, np.int64)
        nearer = np.flatnonzero(t < out.t)
        out.t[nearer] = t[nearer]
        out.face[nearer] = -1
        out.point[nearer] = index[nearer]
        if raw:
            out.raw_point = np.full(len(rays), -1, np.int64)
            first = np.flatnonzero(t < raw_t)
            out.raw_face[first] = -1
            out.raw_point[first] = index[first]
        return out

    def _trace_triangles(self, rays: np.ndarray, raw: bool) -> Hits:
        t, face, bary = self._cast_rays(rays)
        valid = face >= 0
        mat, uv = self.surface(face, bary)
        out = Hits(t, face, bary, mat, uv)
        if raw and self.points is not None:
            out.raw_t = t.copy()  # where repopa's first surface is (a sphere may be nearer)
        mats = self.mats
        if not (mats.cutting or mats.culling):
            if raw:
                out.raw_face, out.raw_bary = face.copy(), bary
            return out
        passes, culled = self._passes(face, mat, uv, rays[:, 3:], valid)
        if raw:
            out.raw_face = face.copy() if culled is None else np.where(culled, -1, face)
            out.raw_bary = bary.copy()
        idx = np.flatnonzero(passes)
        if not len(idx):
            return out
        eps = F32(self.options.epsilon)
        sub = np.take(rays, idx, axis=0)
        d, o0 = sub[:, 3:], sub[:, :3]
        t_acc = t[idx] + eps / np.sqrt(_dot(d, d))
        out.t[idx] = np.inf  # (out.t is t) until a surface behind is found
        out.face[idx] = -1
        for _ in range(self.options.max_layers - 1):
            sub = np.empty((len(idx), 6), F32)
            np.multiply(d, t_acc[:, None], out=sub[:, :3])
            sub[:, :3] += o0
            sub[:, 3:] = d
            tt, ff, bb = self._cast_rays(sub)
            keep = np.flatnonzero(ff >= 0)
            if len(keep) < len(ff):
                tt, ff, t_acc, idx = tt[keep], ff[keep], t_acc[keep], idx[keep]
                bb, d, o0 = (np.take(a, keep, axis=0) for a in (bb, d, o0))
            if not len(idx):
                break
            mat, uv = self.surface(ff, bb)
            passes, culled = self._passes(ff, mat, uv, d)
            if raw:
                first = out.raw_face[idx] < 0
                if culled is not None:
                    first &= ~culled
                out.raw_face[idx[first]] = ff[first]
                out.raw_bary[idx[first]] = bb[first]
                if out.raw_t is not None:
                    out.raw_t[idx[first]] = t_acc[first] + tt[first]
            stop = np.flatnonzero(~passes)
            j = idx[stop]
            out.t[j] = t_acc[stop] + tt[stop]
            out.face[j] = ff[stop]
            out.bary[j] = bb[stop]
            out.mat[j] = mat[stop]
            out.uv[j] = uv[stop]
            go = np.flatnonzero(passes)
            if not len(go):
                break
            d, o0, idx = np.take(d, go, axis=0), np.take(o0, go, axis=0), idx[go]
            t_acc = t_acc[go] + tt[go] + eps / np.sqrt(_dot(d, d))
        return out

    def occluded(self, rays: np.ndarray) -> np.ndarray:
        """Is each ray (K x 6: origin, segment to the light) blocked before ``SHADOW_TFAR`` of
        its segment? Cut-out texels let light through."""
        k = len(rays)
        occ = np.zeros(k, bool)
        eps = F32(self.options.epsilon)
        for sc in sorted(self._scenes, key=lambda sc: sc.cuts):  # opaque scenes first: no walks
            # Each scene tests all rays: cheaper than gathering those still open (most are).
            blocked = sc.scene.test_occlusions(_tensor(rays), tfar=SHADOW_TFAR, nthreads=self.threads).numpy()
            if not sc.cuts:
                occ |= blocked
                continue
            # Blocked, perhaps only by cut-out texels: walk along the segment surface by surface.
            idx = np.flatnonzero(blocked & ~occ)
            sub = np.take(rays, idx, axis=0)
            for _ in range(self.options.max_layers):
                if not len(idx):
                    break
                r = sc.scene.cast_rays(_tensor(sub), nthreads=self.threads)
                t = r["t_hit"].numpy()
                g = r["geometry_ids"].numpy()
                hit = (g != INVALID) & (t < SHADOW_TFAR)
                face = np.take(sc.offset, g, mode="clip")  # (misses: INVALID ids clip, masked by hit)
                face += r["primitive_ids"].numpy()
                face[~hit] = 0
                mat = np.take(self.face_mat, face)
                cut = np.take(self.mats.cuts, mat) & hit
                sel = np.flatnonzero(cut)
                if len(sel):  # UVs only where opacity may let light through
                    uv = self._uv(face[sel], np.take(r["primitive_uvs"].numpy(), sel, axis=0))
                    cut[sel] = ~self.mats.opaque(uv, mat[sel])
                occ[idx[hit & ~cut]] = True
                go = np.flatnonzero(cut)
                idx, sub, t = idx[go], np.take(sub, go, axis=0), t[go]
                # Go on from just past the hit, still aiming at the same point of the light.
                seg = sub[:, 3:]
                step = np.minimum(t + eps / np.sqrt(_dot(seg, seg)), F32(1.0))
                sub[:, :3] += step[:, None] * seg
                seg *= (F32(1.0) - step)[:, None]
            occ[idx] = True  # still among layers of cut-out cards after max_layers: shadowed
        if self.points is not None:
            open_ = np.flatnonzero(~occ)
            occ[open_] = self.points.occluded(np.take(rays, open_, axis=0), SHADOW_TFAR)
        return occ

    def labels(self, hits: Hits, repopa: bool, label_map: np.ndarray, out: dict[str, np.ndarray]) -> None:
        """Labels (``label_map`` applied) and leaf instances of the rays' ``hits`` into ``out``
        (``labels``, and ``instances`` when present): from the kept surfaces, or with ``repopa``
        from the first surface of any opacity (the trace must have been ``raw``)."""
        face = hits.raw_face if repopa else hits.face
        point = hits.raw_point if repopa else hits.point
        if point is not None and self.points is not None:
            on = np.flatnonzero(point >= 0)
            if len(on):
                pts = self.points.points
                lab = np.take(pts.labels, point[on])
                out["labels"][on] = np.take(label_map, lab)
                if "instances" in out and pts.instances is not None:
                    out["instances"][on] = np.where(lab > 0, np.take(pts.instances, point[on]), 0)
        p0, p1 = self.plant_faces
        on_plant = np.flatnonzero((face >= p0) & (face < p1))
        if not len(on_plant):
            return
        face = face[on_plant]
        if repopa:
            mat, uv = self.surface(face, hits.raw_bary[on_plant])
        else:
            mat, uv = hits.mat[on_plant], hits.uv[on_plant]
        lab = self.mats.label(uv, mat)
        if repopa:  # the whole card is plant: unlabelled cut-out texels take the material's organ
            cut = np.flatnonzero(lab == 0)
            if len(cut):
                cut = cut[~self.mats.opaque(uv[cut], mat[cut])]
                lab[cut] = np.take(self.mats.fallback, mat[cut])
        out["labels"][on_plant] = np.take(label_map, lab)
        if "instances" in out:
            out["instances"][on_plant] = np.where(lab > 0, np.take(self.face_inst, face), 0)

    def annotate(self, hits: Hits, repopa: bool, label_map: np.ndarray, out: dict[str, np.ndarray]) -> None:
        """Depth (planar, m, from rays that start on the near plane; 0 where nothing is hit),
        labels and leaf instances of the rays' ``hits`` into ``out``."""
        np.add(hits.t, F32(self.options.near), out=out["depth"])
        out["depth"][~hits.hit] = 0.0
        self.labels(hits, repopa, label_map, out)

    def exact(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        *,
        seg_mode: str,
        label_map: np.ndarray,
        rows_per_batch: int = 256,
    ) -> dict[str, np.ndarray]:
        """The exact images of one view, for renderers that shade by other means: ``labels``,
        ``depth`` (planar, m; 0 where nothing is hit) and ``instances`` (when the plant numbers
        its leaves) from rays through the pixel centres, byte for byte what the raycast renderer
        gives (the same rays, traced by the same code). Place the arms first."""
        H, W = camera.height, camera.width
        x, y = pixel_slopes(camera)
        T = np.asarray(world_T_camera, np.float64)
        out = {"labels": np.zeros(H * W, np.uint8), "depth": np.empty(H * W, F32)}
        if self.has_instances:
            out["instances"] = np.zeros(H * W, np.uint16)
        for r0 in range(0, H, rows_per_batch):  # bounded memory at any resolution
            r1 = min(r0 + rows_per_batch, H)
            part = {k: v[r0 * W : r1 * W] for k, v in out.items()}
            hits = self.trace(camera_rays(x, y[r0:r1], T, self.options.near), raw=seg_mode == "repopa")
            self.annotate(hits, seg_mode == "repopa", label_map, part)
        shape = {"labels": (H, W), "depth": (H, W), "instances": (H, W)}
        return {k: v.reshape(shape[k]) for k, v in out.items()}

    def close(self) -> None:
        """Drop the Embree scenes."""
        self._scenes = []
        self._static_scene = None
