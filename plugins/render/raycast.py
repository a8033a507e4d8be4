"""The ``raycast`` renderer: Open3D's ``RaycastingScene`` (Embree, CPU) with alpha-tested cards.

One primary pass gives RGB, labels and depth together: a ray through each pixel centre (OpenCV:
direction ``K^-1 [u, v, 1]``, so the hit distance in units of that direction *is* the planar z).

Opacity. Embree knows nothing of textures, so a hit on a texel that opacity cuts away (a
``MASK``/``BLEND`` material whose albedo alpha is below its cutoff, compared in 8 bits exactly as
:func:`agrisim.texturing.opaque`) is skipped here: the ray is cast again from just past that hit
(``epsilon`` metres along it), up to ``max_layers`` times; rays still on cut-out texels after that
count as hitting nothing. Back faces of single-sided materials are skipped the same way (glTF back
face culling). RGB and depth come from the first surface that is left.

Labels. Only the plant mesh (``scene.plant``) carries labels; its label texture is sampled
*nearest* at the hit's UV. ``seg_mode="texture"`` labels the first opaque hit (the paper's
method); ``seg_mode="repopa"`` ignores opacity for labels only (EasySynth's way): the first hit of
any card decides, a cut-out texel taking its label texture's value there or, where that is 0,
the material's most common non-zero label. ``labels="plant"`` maps every non-zero id to 1.

Shading. Lambert with the scene's lights plus an ambient term, albedo converted from sRGB to
linear, tone-mapped back to sRGB. Units are renderer-relative: a light of ``intensity`` I at
distance r lights a surface facing it with irradiance ``I / r^2`` (times the light's colour, its
emission cosine for ``area`` discs, its cone for ``spot`` lights); outgoing radiance is albedo x
irradiance, so a white surface under irradiance 1 (after ``exposure``) is white.

Shadows. ``shadow_samples`` N rays per pixel are shared among the lights: each picks a light with
probability proportional to its unshadowed contribution there and a point on it (uniform on an
area light's disc), so penumbras are soft and unshadowed pixels carry no noise. Shadow rays skip
cut-out texels like primary rays (light passes through holes in cards). Sampling is seeded from
``seed`` and the camera, so the same inputs give byte-identical images. N = 0 is hard-lit, without
shadows. With ``supersample`` s > 1, RGB is the mean of s x s rays per pixel (each with
``ceil(N / s^2)`` shadow rays); labels and depth stay exact at the pixel centres.

Arms: their visual meshes are loaded once and placed per frame at ``link_poses`` in a second
small scene (rebuilt only when the poses change); the nearer of the two hits wins.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from agrisim import BackendSpec, hookimpl
from agrisim.cell import Cell
from agrisim.interfaces import CameraModel, Frame, Renderer
from agrisim.quiet import native_output_silenced
from agrisim.scene import Light, Material, Mesh, Scene

with native_output_silenced():
    import open3d as o3d

from agrisim.plugins.render.arm_meshes import arm_link_meshes

F32 = np.float32
INVALID = np.uint32(0xFFFFFFFF)


class RaycastOptions(BaseModel):
    """Options of the raycast (Open3D/Embree) renderer."""

    model_config = ConfigDict(extra="forbid", use_attribute_docstrings=True)

    ambient: float = Field(0.15, ge=0.0, le=100.0)
    """Ambient irradiance added everywhere (a white surface lit by ambient 1 alone is white)."""
    exposure: float = Field(1.0, gt=0.0, le=1e6)
    """Scale of the linear radiance before tone mapping."""
    tonemap: Literal["clip", "reinhard"] = "clip"
    """Linear to display: ``clip`` keeps albedos exact up to white; ``reinhard`` (x / (1 + x)) rolls
    highlights off smoothly."""
    max_layers: int = Field(16, ge=1, le=256)
    """Most surfaces a ray passes (cut-out texels, culled back faces) before it counts as a miss."""
    near: float = Field(1e-3, ge=0.0, le=1.0)
    """Near clipping plane (planar z), m: nothing closer is seen, e.g. the camera's own body."""
    epsilon: float = Field(1e-4, gt=0.0, le=0.01)
    """Offset, m, of a ray continuing past a cut-out texel and of a shadow ray's origin off its surface."""
    seed: int = Field(0, ge=0, le=2**32 - 1)
    """Seed of shadow sampling (mixed with the camera pose: every view has its own stream)."""
    background: tuple[int, int, int] = (0, 0, 0)
    """sRGB colour of pixels that hit nothing."""
    threads: int = Field(0, ge=0, le=1024)
    """Embree threads (0: all cores)."""


# ----------------------------------------------------------------------------- colour


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(np.maximum(c, 0.0031308), 1 / 2.4) - 0.055)


#: uint8 sRGB -> linear float32
SRGB_TO_LINEAR = _srgb_to_linear(np.arange(256) / 255.0).astype(F32)
#: linear in [0, 1] quantised to ENCODE_STEPS + 1 levels -> uint8 sRGB
ENCODE_STEPS = 16383
LINEAR_TO_SRGB8 = np.round(_linear_to_srgb(np.arange(ENCODE_STEPS + 1) / ENCODE_STEPS) * 255.0).astype(np.uint8)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


# -------------------------------------------------------------------------- materials


class _Materials:
    """Every material's textures packed into flat buffers, so that lookups for hits on any mix of
    materials are one vectorised gather (index = offset + row * width + col)."""

    def __init__(self) -> None:
        self.materials: list[Material] = []
        self.labelled: list[bool] = []
        self._alb: list[np.ndarray] = [np.full((1, 4), 255, np.uint8)]  # shared white texel
        self._alb_size = 1
        self._lab: list[np.ndarray] = []
        self._lab_size = 0
        self._alb_at: dict[int, int] = {}
        self._lab_at: dict[int, tuple[int, int]] = {}  # id(texture) -> (offset, most common non-zero)
        self._const_at: dict[int, int] = {}
        self.rows: list[tuple] = []

    def add(self, m: Material, labelled: bool) -> int:
        if m.albedo is not None:
            key = id(m.albedo)
            if key not in self._alb_at:
                self._alb_at[key] = self._alb_size
                flat = np.ascontiguousarray(m.albedo).reshape(-1, 4)
                self._alb.append(flat)
                self._alb_size += len(flat)
            alb = (self._alb_at[key], *m.albedo.shape[:2])
        else:
            alb = (0, 1, 1)
        if m.labels is not None:
            key = id(m.labels)
            if key not in self._lab_at:
                flat = np.ascontiguousarray(m.labels).reshape(-1)
                counts = np.bincount(flat, minlength=256)
                counts[0] = 0
                common = int(counts.argmax()) if counts.any() else int(m.label)
                self._lab_at[key] = (self._lab_size, common)
                self._lab.append(flat)
                self._lab_size += len(flat)
            off, common = self._lab_at[key]
            lab = (off, *m.labels.shape[:2])
        else:
            if m.label not in self._const_at:
                self._const_at[m.label] = self._lab_size
                self._lab.append(np.array([m.label], np.uint8))
                self._lab_size += 1
            lab, common = (self._const_at[m.label], 1, 1), int(m.label)
        if m.cuts:  # smallest 8-bit alpha a with a / 255 >= cutoff, as texturing.opaque compares
            ok = np.arange(256) / 255.0 >= m.alpha_cutoff
            thr = int(np.argmax(ok)) if ok.any() else 256
        else:
            thr = 0
        self.materials.append(m)
        self.labelled.append(labelled)
        self.rows.append((alb, lab, thr, common, m.double_sided, m.color))
        return len(self.materials) - 1

    def finish(self) -> None:
        rows = self.rows
        self.alb_flat = np.concatenate(self._alb)
        self.lab_flat = np.concatenate(self._lab) if self._lab else np.zeros(1, np.uint8)
        self.alb_off = np.array([r[0][0] for r in rows], np.int64)
        self.alb_h = np.array([r[0][1] for r in rows], np.int64)
        self.alb_w = np.array([r[0][2] for r in rows], np.int64)
        self.lab_off = np.array([r[1][0] for r in rows], np.int64)
        self.lab_h = np.array([r[1][1] for r in rows], np.int64)
        self.lab_w = np.array([r[1][2] for r in rows], np.int64)
        self.threshold = np.array([r[2] for r in rows], np.int16)
        self.fallback = np.array([r[3] for r in rows], np.uint8)
        self.double_sided = np.array([r[4] for r in rows], bool)
        color = np.array([r[5] for r in rows], np.float64).reshape(-1, 4)
        self.color = color[:, :3].astype(F32)
        self.cutting = bool((self.threshold > 0).any())
        self.culling = bool((~self.double_sided).any())

    @staticmethod
    def _index(uv: np.ndarray, off: np.ndarray, h: np.ndarray, w: np.ndarray, mat: np.ndarray) -> np.ndarray:
        # Same arithmetic as agrisim.texturing.texel_index (float64 product, floor, wrap).
        wm, hm = w[mat], h[mat]
        cols = np.floor(uv[:, 0].astype(np.float64) * wm).astype(np.int64) % wm
        rows = np.floor(uv[:, 1].astype(np.float64) * hm).astype(np.int64) % hm
        return off[mat] + rows * wm + cols

    def albedo_index(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        return self._index(uv, self.alb_off, self.alb_h, self.alb_w, mat)

    def opaque(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        """Is each hit on a texel opacity keeps? (materials that do not cut: always)"""
        if not self.cutting:
            return np.ones(len(mat), bool)
        return self.alb_flat[self.albedo_index(uv, mat), 3] >= self.threshold[mat]

    def label(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        return self.lab_flat[self._index(uv, self.lab_off, self.lab_h, self.lab_w, mat)]


def _face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return (n / np.where(length > 0, length, 1.0)).astype(F32)


def _tensor(a: np.ndarray) -> o3d.core.Tensor:
    return o3d.core.Tensor.from_numpy(np.ascontiguousarray(a))


# ---------------------------------------------------------------------------- the arms


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
    n_faces: int
    face0: int  # first face of this arm in the renderer's global face arrays


@dataclass
class _Hits:
    t: np.ndarray  # (K,) float32 distance in ray-direction units from the pass's origins; inf: miss
    face: np.ndarray  # (K,) int64 global face index, -1: miss
    bary: np.ndarray  # (K, 2) float32 Open3D/Embree barycentrics
    raw_face: np.ndarray | None = None  # first hit of any opacity (repopa's label pass)
    raw_bary: np.ndarray | None = None


# --------------------------------------------------------------------------- renderer


class RaycastRenderer(Renderer):
    """Embree ray casting through Open3D: exact depth and labels, alpha-tested cards, soft shadows."""

    def __init__(self, scene: Scene, cell: Cell, settings: object, options: RaycastOptions) -> None:
        super().__init__(scene, cell, settings, options)
        self.seg_mode = getattr(settings, "seg_mode", "texture")
        self.shadow_samples = int(getattr(settings, "shadow_samples", 1))
        self.supersample = int(getattr(settings, "supersample", 1))
        self.hide_robots = bool(getattr(settings, "hide_robots", False))
        organs = getattr(settings, "labels", "plant") == "organs"
        self.label_map = np.arange(256, dtype=np.uint8) if organs else (np.arange(256) > 0).astype(np.uint8)
        self.threads = options.threads

        mats = _Materials()
        face_mat, face_uv, face_normal, face_plant, face_inst = [], [], [], [], []
        self.static = o3d.t.geometry.RaycastingScene(nthreads=self.threads)
        geom_offset: dict[int, int] = {}
        n_faces = 0
        self.has_instances = False
        for mesh in scene.meshes:
            if len(mesh.faces) == 0:
                continue
            plant = mesh.name == scene.plant
            index = np.array([mats.add(m, plant) for m in mesh.materials], np.int32)
            gid = self.static.add_triangles(
                _tensor(mesh.vertices.astype(F32)), _tensor(mesh.faces.astype(np.uint32))
            )
            geom_offset[int(gid)] = n_faces
            face_mat.append(index[mesh.face_material])
            if mesh.uvs is not None:
                face_uv.append(mesh.uvs[mesh.faces])
            else:
                face_uv.append(np.zeros((len(mesh.faces), 3, 2), F32))
            face_normal.append(_face_normals(mesh.vertices, mesh.faces))
            face_plant.append(np.full(len(mesh.faces), plant))
            if plant and mesh.face_instance is not None:
                self.has_instances = True
                face_inst.append(mesh.face_instance)
            else:
                face_inst.append(np.zeros(len(mesh.faces), np.uint16))
            n_faces += len(mesh.faces)
        self.n_static = n_faces
        self.geom_offset = np.zeros(max(geom_offset, default=-1) + 1, np.int64)
        for gid, off in geom_offset.items():
            self.geom_offset[gid] = off

        self.arms: list[_Arm] = []
        if not self.hide_robots:
            for arm in cell.arms:
                links, faces, nv = [], [], 0
                f0 = n_faces
                for lm in arm_link_meshes(arm.urdf):
                    mesh = lm.mesh
                    index = np.array([mats.add(m, False) for m in mesh.materials], np.int32)
                    links.append(
                        _ArmLink(lm.link, mesh.vertices, _face_normals(mesh.vertices, mesh.faces), nv, n_faces - f0)
                    )
                    faces.append(mesh.faces + nv)
                    face_mat.append(index[mesh.face_material])
                    face_uv.append(np.zeros((len(mesh.faces), 3, 2), F32))
                    face_normal.append(np.zeros((len(mesh.faces), 3), F32))  # filled per frame
                    face_plant.append(np.zeros(len(mesh.faces), bool))
                    face_inst.append(np.zeros(len(mesh.faces), np.uint16))
                    nv += len(mesh.vertices)
                    n_faces += len(mesh.faces)
                if links:
                    all_faces = np.concatenate(faces).astype(np.uint32)
                    self.arms.append(_Arm(arm.name, links, _tensor(all_faces), nv, len(all_faces), f0))
        mats.finish()
        self.mats = mats
        cat = np.concatenate
        self.face_mat = cat(face_mat) if face_mat else np.zeros(0, np.int32)
        self.face_uv = cat(face_uv) if face_uv else np.zeros((0, 3, 2), F32)
        self.face_normal = cat(face_normal) if face_normal else np.zeros((0, 3), F32)
        self.face_plant = cat(face_plant) if face_plant else np.zeros(0, bool)
        self.face_inst = cat(face_inst) if face_inst else np.zeros(0, np.uint16)
        self.has_static = self.n_static > 0
        self._arm_scene: o3d.t.geometry.RaycastingScene | None = None
        self._arm_offset = np.zeros(0, np.int64)
        self._arm_key: bytes | None = None
        self._rays_cache: tuple[tuple, np.ndarray] | None = None
        self._lights = _LightTable(scene.lights)

    # ---------------------------------------------------------------- geometry per frame
    def _place_arms(self, link_poses: Mapping[str, Mapping[str, np.ndarray]]) -> None:
        arms = [a for a in self.arms if a.name in link_poses]
        if not arms:
            self._arm_scene = None
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
        scene = o3d.t.geometry.RaycastingScene(nthreads=self.threads)
        offsets: dict[int, int] = {}
        k = 0
        for arm in arms:
            verts = np.empty((arm.n_vertices, 3), F32)
            for link in arm.links:
                T = poses[k]
                k += 1
                R, t = T[:3, :3], T[:3, 3]
                verts[link.v0 : link.v0 + len(link.vertices)] = link.vertices @ R.T + t
                f = arm.face0 + link.f0
                self.face_normal[f : f + len(link.normals)] = link.normals @ R.T
            gid = scene.add_triangles(_tensor(verts), arm.faces)
            offsets[int(gid)] = arm.face0
        self._arm_offset = np.zeros(max(offsets) + 1, np.int64)
        for gid, off in offsets.items():
            self._arm_offset[gid] = off
        self._arm_scene = scene
        self._arm_key = key

    # -------------------------------------------------------------------------- casting
    def _cast(self, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest hit of each ray in the static and the arm scene: (t, global face, barycentrics)."""
        k = len(dirs)
        rays = np.empty((k, 6), F32)
        rays[:, :3] = origins
        rays[:, 3:] = dirs
        return self._cast_rays(rays)

    def _cast_rays(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k = len(rays)
        tensor = _tensor(rays)
        if self.has_static:
            r = self.static.cast_rays(tensor, nthreads=self.threads)
            t = r["t_hit"].numpy()
            g = r["geometry_ids"].numpy()
            hit = g != INVALID
            face = np.where(hit, self.geom_offset[np.where(hit, g, 0)] + r["primitive_ids"].numpy(), -1)
            bary = r["primitive_uvs"].numpy()
        else:
            t = np.full(k, np.inf, F32)
            face = np.full(k, -1, np.int64)
            bary = np.zeros((k, 2), F32)
        if self._arm_scene is not None:
            r = self._arm_scene.cast_rays(tensor, nthreads=self.threads)
            ta = r["t_hit"].numpy()
            nearer = np.flatnonzero(ta < t)
            if len(nearer):
                t[nearer] = ta[nearer]
                g = r["geometry_ids"].numpy()[nearer]
                face[nearer] = self._arm_offset[g] + r["primitive_ids"].numpy()[nearer]
                bary[nearer] = r["primitive_uvs"].numpy()[nearer]
        return t, face, bary

    def _uv(self, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
        # Same arithmetic as agrisim.texturing.interpolate_uv, on pre-gathered corner UVs.
        tri = self.face_uv[face]
        w1, w2 = bary[:, 0:1], bary[:, 1:2]
        return (1.0 - w1 - w2) * tri[:, 0] + w1 * tri[:, 1] + w2 * tri[:, 2]

    def _trace(self, origins: np.ndarray, dirs: np.ndarray, raw: bool, rays: np.ndarray | None = None) -> _Hits:
        """First surface along each ray that is not a cut-out texel or a culled back face; with
        ``raw`` also the first surface of any opacity (culled back faces still skipped)."""
        k = len(dirs)
        out = _Hits(np.full(k, np.inf, F32), np.full(k, -1, np.int64), np.zeros((k, 2), F32))
        if raw:
            out.raw_face = np.full(k, -1, np.int64)
            out.raw_bary = np.zeros((k, 2), F32)
        mats = self.mats
        idx = None  # active rays (None: all)
        t_acc = None
        d = dirs
        for layer in range(self.options.max_layers):
            if layer == 0:
                t, face, bary = self._cast_rays(rays) if rays is not None else self._cast(origins, dirs)
            else:
                o = origins[idx] + t_acc[:, None] * d
                t, face, bary = self._cast(o, d)
            hit = np.flatnonzero(face >= 0)
            if len(hit) < len(face):
                t, face, bary = t[hit], face[hit], bary[hit]
                idx = hit if idx is None else idx[hit]
                d = d[hit]
                if t_acc is not None:
                    t_acc = t_acc[hit]
            if idx is None:
                idx = np.arange(k)
            if not len(idx):
                break
            if not (mats.cutting or mats.culling):
                passes = np.zeros(len(idx), bool)
                culled = passes
            else:
                mat = self.face_mat[face]
                passes = ~mats.opaque(self._uv(face, bary), mat)
                if mats.culling:
                    culled = ~mats.double_sided[mat] & (_dot(self.face_normal[face], d) > 0)
                    passes |= culled
                else:
                    culled = np.zeros(len(idx), bool)
            if raw:
                first = (out.raw_face[idx] < 0) & ~culled
                out.raw_face[idx[first]] = face[first]
                out.raw_bary[idx[first]] = bary[first]
            stop = np.flatnonzero(~passes)
            total = t if t_acc is None else t_acc + t
            out.t[idx[stop]] = total[stop]
            out.face[idx[stop]] = face[stop]
            out.bary[idx[stop]] = bary[stop]
            go = np.flatnonzero(passes)
            if not len(go):
                break
            d = d[go]
            step = self.options.epsilon / np.sqrt(_dot(d, d))
            t_acc = (total[go] + step).astype(F32)
            idx = idx[go]
        return out

    def _occluded(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Is the segment origin -> origin + dir blocked? Cut-out texels let light through."""
        k = len(dirs)
        rays = np.empty((k, 6), F32)
        rays[:, :3] = origins
        rays[:, 3:] = dirs
        occ = np.zeros(k, bool)
        if self._arm_scene is not None:
            occ |= self._arm_scene.test_occlusions(_tensor(rays), tfar=1.0, nthreads=self.threads).numpy()
        if not self.has_static:
            return occ
        idx = np.flatnonzero(~occ)
        rays = rays[idx]
        mats = self.mats
        for _ in range(self.options.max_layers):
            blocked = self.static.test_occlusions(_tensor(rays), tfar=1.0, nthreads=self.threads).numpy()
            if not mats.cutting:
                occ[idx] = blocked
                return occ
            sel = np.flatnonzero(blocked)
            if not len(sel):
                return occ
            idx, rays = idx[sel], rays[sel]
            r = self.static.cast_rays(_tensor(rays), nthreads=self.threads)
            t = r["t_hit"].numpy()
            g = r["geometry_ids"].numpy()
            hit = (g != INVALID) & (t < 1.0)
            face = np.where(hit, self.geom_offset[np.where(hit, g, 0)] + r["primitive_ids"].numpy(), 0)
            opaque = mats.opaque(self._uv(face, r["primitive_uvs"].numpy()), self.face_mat[face])
            occ[idx[hit & opaque]] = True
            go = np.flatnonzero(hit & ~opaque)
            if not len(go):
                return occ
            idx, rays, t = idx[go], rays[go], t[go]
            target = rays[:, :3] + rays[:, 3:]
            d = rays[:, 3:]
            o = rays[:, :3] + (t + self.options.epsilon / np.sqrt(_dot(d, d)))[:, None] * d
            rays = np.concatenate([o, target - o], axis=1).astype(F32)
        occ[idx] = True  # still inside layers of cut-out cards: call it shadowed
        return occ

    # -------------------------------------------------------------------------- shading
    def _shade(
        self, origin: np.ndarray, dirs: np.ndarray, hits: _Hits, rng: np.random.Generator, samples: int
    ) -> np.ndarray:
        """Linear radiance (K x 3) of the hit surfaces (0 where nothing was hit); ``origin`` is the
        rays' origin (K x 3, or one point) from which ``hits.t`` counts."""
        k = len(dirs)
        out = np.zeros((k, 3), F32)
        sel = np.flatnonzero(hits.face >= 0)
        if not len(sel):
            return out
        face, d = hits.face[sel], dirs[sel]
        mat = self.face_mat[face]
        uv = self._uv(face, hits.bary[sel])
        albedo = SRGB_TO_LINEAR[self.mats.alb_flat[self.mats.albedo_index(uv, mat), :3]]
        albedo *= self.mats.color[mat]
        p = (origin[sel] if origin.ndim == 2 else origin) + hits.t[sel, None] * d
        n = self.face_normal[face]
        n = np.where((_dot(n, d) > 0)[:, None], -n, n)  # Lambert on the side the camera sees
        irradiance = self._lights.irradiance(p, n, samples, rng, self._occluded, self.options.epsilon)
        irradiance += F32(self.options.ambient)
        out[sel] = albedo * irradiance
        return out

    def _encode(self, linear: np.ndarray, hit: np.ndarray) -> np.ndarray:
        x = linear * F32(self.options.exposure)
        if self.options.tonemap == "reinhard":
            x = x / (1.0 + x)
        q = (np.clip(x, 0.0, 1.0) * ENCODE_STEPS + 0.5).astype(np.int32)
        rgb = LINEAR_TO_SRGB8[q]
        rgb[~hit] = np.asarray(self.options.background, np.uint8)
        return rgb

    # --------------------------------------------------------------------------- render
    def _camera_dirs(self, camera: CameraModel) -> np.ndarray:
        """K^-1 [u, v, 1] of every pixel centre (H*W x 3, camera frame, z = 1)."""
        key = (camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy)
        if self._rays_cache is None or self._rays_cache[0] != key:
            u = (np.arange(camera.width, dtype=np.float64) - camera.cx) / camera.fx
            v = (np.arange(camera.height, dtype=np.float64) - camera.cy) / camera.fy
            d = np.empty((camera.height, camera.width, 3), np.float64)
            d[..., 0] = u[None, :]
            d[..., 1] = v[:, None]
            d[..., 2] = 1.0
            self._rays_cache = (key, d.reshape(-1, 3))
        return self._rays_cache[1]

    def _seed(self, camera: CameraModel, world_T_camera: np.ndarray) -> int:
        h = hashlib.blake2b(digest_size=8)
        h.update(np.asarray(world_T_camera, np.float64).tobytes())
        h.update(np.array([camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy], np.float64).tobytes())
        h.update(int(self.options.seed).to_bytes(8, "little"))
        return int.from_bytes(h.digest(), "little")

    def render(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> Frame:
        H, W = camera.height, camera.width
        if self.arms:
            self._place_arms(link_poses)
        T = np.asarray(world_T_camera, np.float64)
        R, c = T[:3, :3], T[:3, 3]
        d_cam = self._camera_dirs(camera)
        dirs = (d_cam @ R.T).astype(F32)  # z_camera component 1: t is planar depth
        near = self.options.near
        rays = np.empty((len(dirs), 6), F32)
        rays[:, :3] = c
        rays[:, 3:] = dirs
        if near > 0:
            rays[:, :3] += F32(near) * dirs
        origins = rays[:, :3]
        rng = np.random.default_rng(self._seed(camera, T))

        hits = self._trace(origins, dirs, raw=self.seg_mode == "repopa", rays=rays)
        hit = hits.face >= 0
        depth = np.where(hit, hits.t + F32(near), F32(0.0)).astype(F32)

        # Labels: the first opaque hit (texture) or the first hit of any opacity (repopa).
        if self.seg_mode == "repopa":
            lface, lbary = hits.raw_face, hits.raw_bary
        else:
            lface, lbary = hits.face, hits.bary
        labels = np.zeros(len(dirs), np.uint8)
        instances = np.zeros(len(dirs), np.uint16) if self.has_instances else None
        on_plant = np.flatnonzero(lface >= 0)
        on_plant = on_plant[self.face_plant[lface[on_plant]]]
        if len(on_plant):
            face = lface[on_plant]
            mat = self.face_mat[face]
            uv = self._uv(face, lbary[on_plant])
            lab = self.mats.label(uv, mat)
            if self.seg_mode == "repopa":
                cut = (lab == 0) & ~self.mats.opaque(uv, mat)
                lab[cut] = self.mats.fallback[mat[cut]]
            labels[on_plant] = self.label_map[lab]
            if instances is not None:
                instances[on_plant] = np.where(lab > 0, self.face_inst[face], 0)

        s = self.supersample
        n = self.shadow_samples
        if s == 1:
            linear = self._shade(origins, dirs, hits, rng, n)
            rgb_hit = hit
        else:
            linear = np.zeros((len(dirs), 3), F32)
            count = np.zeros(len(dirs), np.int32)
            n_sub = math.ceil(n / (s * s)) if n > 0 else 0
            for i in range(s):
                for j in range(s):
                    du, dv = (j + 0.5) / s - 0.5, (i + 0.5) / s - 0.5
                    sub = d_cam + np.array([du / camera.fx, dv / camera.fy, 0.0])
                    sdirs = (sub @ R.T).astype(F32)
                    o = (c + near * sdirs).astype(F32)
                    shits = self._trace(o, sdirs, raw=False)
                    linear += self._shade(o, sdirs, shits, rng, n_sub)
                    count += shits.face >= 0
            rgb_hit = count > 0
            linear /= F32(s * s)
        rgb = self._encode(linear, rgb_hit)
        return Frame(
            rgb=rgb.reshape(H, W, 3),
            labels=labels.reshape(H, W),
            depth=depth.reshape(H, W),
            instances=None if instances is None else instances.reshape(H, W),
        )

    def close(self) -> None:
        self._arm_scene = None


class _LightTable:
    """The scene's lights as arrays, and their irradiance at surface points."""

    def __init__(self, lights: list[Light]) -> None:
        self.n = len(lights)
        self.position = np.array([np.asarray(li.position, np.float64) for li in lights], F32).reshape(-1, 3)
        d = np.array([np.asarray(li.direction, np.float64) for li in lights]).reshape(-1, 3)
        norm = np.linalg.norm(d, axis=1, keepdims=True)
        self.direction = (d / np.where(norm > 0, norm, 1.0)).astype(F32)
        self.color = np.array([li.color for li in lights], F32).reshape(-1, 3)
        self.intensity = np.array([li.intensity for li in lights], F32)
        self.kind = [li.kind for li in lights]
        self.radius = np.array([li.radius if li.kind == "area" else 0.0 for li in lights], F32)
        # Spot cones: full inside 90% of the half angle, smooth to 0 at the edge.
        cone = np.radians([min(max(li.cone_deg, 0.0), 180.0) for li in lights])
        self.cos_outer = np.cos(cone).astype(F32)
        self.cos_inner = np.cos(0.9 * cone).astype(F32)
        # An orthonormal basis of each disc, for sampling points on area lights.
        e1 = np.cross(self.direction, np.array([0.0, 0.0, 1.0]))
        small = np.linalg.norm(e1, axis=1) < 1e-6
        e1[small] = np.cross(self.direction[small], np.array([1.0, 0.0, 0.0]))
        e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-12)
        self.e1 = e1.astype(F32)
        self.e2 = np.cross(self.direction, e1).astype(F32)
        self.luminance = self.color.mean(axis=1) if self.n else np.zeros(0, F32)

    def _weights(self, p: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Unshadowed scalar irradiance (L x K) of each light at points ``p`` with normals ``n``
        (light colour's mean; centre of area lights)."""
        w = np.zeros((self.n, len(p)), F32)
        for i in range(self.n):
            lv = self.position[i] - p
            r2 = _dot(lv, lv)
            inv_r = 1.0 / np.sqrt(np.maximum(r2, F32(1e-12)))
            cos_s = _dot(n, lv) * inv_r
            cos_e = -(lv @ self.direction[i]) * inv_r
            if self.kind[i] == "area":
                emit = np.maximum(cos_e, 0.0)
            elif self.kind[i] == "spot":
                lo, hi = self.cos_outer[i], self.cos_inner[i]
                x = np.clip((cos_e - lo) / max(hi - lo, 1e-6), 0.0, 1.0)
                emit = x * x * (3.0 - 2.0 * x)
            else:
                emit = 1.0
            w[i] = self.intensity[i] * self.luminance[i] * np.maximum(cos_s, 0.0) * emit / np.maximum(r2, F32(1e-12))
        return w

    def irradiance(self, p, n, samples, rng, occluded, epsilon) -> np.ndarray:  # noqa: ANN001
        """Irradiance (K x 3) at points ``p`` with normals ``n`` from all lights, with ``samples``
        shadow rays per point shared among them (0: no shadows)."""
        k = len(p)
        out = np.zeros((k, 3), F32)
        if not self.n:
            return out
        w = self._weights(p, n)
        # Colour per unit of the scalar weight (the mean of the light colour).
        tint = self.color / np.maximum(self.luminance, 1e-12)[:, None]
        if samples <= 0:
            for i in range(self.n):
                out += w[i][:, None] * tint[i]
            return out
        total = w.sum(axis=0)
        lit = np.flatnonzero(total > 0)
        if not len(lit):
            return out
        w, total = w[:, lit], total[lit]
        cum = np.cumsum(w, axis=0)
        origins = p[lit] + F32(epsilon) * n[lit]
        acc = np.zeros((len(lit), 3), F32)
        for _ in range(samples):
            u = rng.random(len(lit), dtype=F32) * total
            which = np.zeros(len(lit), np.intp)
            for i in range(self.n - 1):
                which += u >= cum[i]
            target = self.position[which].copy()
            radius = self.radius[which]
            if self.radius.any():
                r = radius * np.sqrt(rng.random(len(lit), dtype=F32))
                phi = rng.random(len(lit), dtype=F32) * F32(2 * np.pi)
                target += (r * np.cos(phi))[:, None] * self.e1[which] + (r * np.sin(phi))[:, None] * self.e2[which]
            seg = target - origins
            # Stop 1 mm short of the light: a lamp's own housing must not shadow it.
            length = np.sqrt(_dot(seg, seg))
            seg *= (np.maximum(length - 1e-3, 0.0) / np.maximum(length, 1e-12))[:, None]
            visible = ~occluded(origins, seg)
            acc += tint[which] * visible[:, None]
        out[lit] = acc * (total / F32(samples))[:, None]
        return out


@hookimpl
def agrisim_renderers() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="raycast",
            factory=RaycastRenderer,
            description="Open3D RaycastingScene (Embree, CPU): exact depth and texture labels, alpha-tested cards, soft shadows",
            options_model=RaycastOptions,
            limits="Lambert shading with direct light and an ambient term (no reflections, no indirect light); "
            "nearest-texel albedo; alpha is a step at the cutoff (no blending)",
        )
    ]
