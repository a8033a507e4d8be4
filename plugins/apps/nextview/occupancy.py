"""What the camera has seen so far, as a voxel map around the plant: each voxel unknown, free
(a view's ray passed through it), occupied (a ray ended in it) or plant (a ray ended in it on a
pixel the camera's segmentation calls plant), and the volumetric information gain of a
candidate view: the unknown voxels its rays would reach before they meet an occupied one
(Isler et al. 2016's "unobserved voxels"; Delmerico et al. 2018 compare this family).
Built from what the views measured only: depth, segmentation and poses, never the truth.

Rays are marched in steps of half a voxel, every ``stride``-th pixel of a view: a plain NumPy
traversal, exact enough for a map whose voxels are a centimetre across, and free of a C++
octree dependency.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from agrisim.scene.camera import CameraModel

UNKNOWN, FREE, OCCUPIED, PLANT = 0, 1, 2, 3


@dataclass
class VoxelMap:
    """``cells`` (G x G x G uint8: :data:`UNKNOWN`, :data:`FREE`, :data:`OCCUPIED`, :data:`PLANT`) over the cube
    of side ``size_m`` whose lowest corner is ``origin`` (world frame)."""

    origin: np.ndarray
    size_m: float
    cells: np.ndarray
    #: each plant voxel's surface normal as the first view to hit it measured it (G x G x G x 3)
    normals: np.ndarray | None = None
    #: the sides of each plant voxel's surface seen so far: 1 its normal's side, 2 the other
    sides: np.ndarray | None = None

    @classmethod
    def around(cls, centre: np.ndarray, size_m: float = 0.5, cells: int = 40) -> VoxelMap:
        """An all-unknown map: a cube of ``size_m`` centred on ``centre``, ``cells`` a side."""
        origin = np.asarray(centre, float) - size_m / 2.0
        shape = (cells, cells, cells)
        return cls(
            origin,
            float(size_m),
            np.zeros(shape, np.uint8),
            np.zeros((*shape, 3), np.float32),
            np.zeros(shape, np.uint8),
        )

    @property
    def voxel_m(self) -> float:
        return self.size_m / self.cells.shape[0]

    def _march(self, origin: np.ndarray, directions: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Voxel indices (R x K x 3, int) along rays from ``origin`` along unit ``directions``
        (R x 3), sampled every half voxel from where each enters the cube up to ``lengths`` (R)
        or its exit, and which samples are live (R x K: inside the cube and before the end)."""
        near, far = self._span(origin, directions, lengths)
        step = self.voxel_m / 2.0
        count = int(np.ceil(max(float((far - near).max(initial=0.0)), 0.0) / step)) + 1
        t = near[:, None] + step * np.arange(count)[None, :]
        live = t <= far[:, None]
        n = self.cells.shape[0]
        index = np.empty((*t.shape, 3), np.int64)
        for axis in range(3):  # an axis at a time, in place: the same arithmetic, 3x faster
            p = directions[:, axis, None] * t
            p += origin[axis]
            p -= self.origin[axis]
            p /= self.voxel_m
            i = np.floor(p, out=p).astype(np.int64)
            live &= (i >= 0) & (i < n)
            index[..., axis] = np.clip(i, 0, n - 1, out=i)
        return index, live

    def _span(self, origin: np.ndarray, directions: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where each ray enters the cube and where it leaves it or ends (``lengths``), m."""
        lo, hi = self.origin, self.origin + self.size_m
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = (lo - origin) / directions
            t1 = (hi - origin) / directions
        near = np.nanmax(np.minimum(t0, t1), axis=1).clip(min=0.0)
        far = np.minimum(np.nanmin(np.maximum(t0, t1), axis=1), lengths)
        return near, far

    def _march_flat(self, origin: np.ndarray, directions: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        """The flat voxel indices (into ``cells.ravel()``) :meth:`_march` gives for its live
        samples, in no order: each ray only as long as it is (a ray that hits the plant early
        does not pay for the longest)."""
        near, far = self._span(origin, directions, lengths)
        step = self.voxel_m / 2.0
        counts = np.where(far >= near, np.floor((far - near) / step).astype(np.int64) + 1, 0)
        ray = np.repeat(np.arange(len(counts)), counts)
        k = np.arange(len(ray)) - np.repeat(np.cumsum(counts) - counts, counts)
        t = near[ray] + step * k
        n = self.cells.shape[0]
        flat = np.zeros(len(ray), np.int64)
        inside = np.ones(len(ray), bool)
        for axis in range(3):  # an axis at a time, in place: the same arithmetic, 3x faster
            p = directions[:, axis][ray] * t
            p += origin[axis]
            p -= self.origin[axis]
            p /= self.voxel_m
            i = np.floor(p, out=p).astype(np.int64)
            inside &= (i >= 0) & (i < n)
            flat *= n
            flat += i
        return flat[inside]

    def integrate(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        depth: np.ndarray,
        labels: np.ndarray | None = None,
        stride: int = 4,
    ) -> None:
        """Add a view: along each sampled pixel's ray the voxels before its depth become free
        (unless already occupied), the voxel at its depth occupied (plant where ``labels`` is
        above 0); a pixel without depth (0) frees its whole ray."""
        v, u = np.mgrid[stride // 2 : camera.height : stride, stride // 2 : camera.width : stride]
        u, v = u.ravel(), v.ravel()
        sx, sy = camera.rays(u.astype(np.float64), v.astype(np.float64))
        slopes = np.column_stack([sx, sy, np.ones_like(sx)])
        norm = np.linalg.norm(slopes, axis=1)
        R, t = world_T_camera[:3, :3], world_T_camera[:3, 3]
        directions = (slopes / norm[:, None]) @ R.T
        z = depth[v, u].astype(np.float64)
        hit = z > 0
        distance = np.where(hit, z * norm, np.inf)  # depth is along the axis; the ray is longer
        # free up to half a voxel short of the surface, so the surface's own voxel stays occupied
        free = self._march_flat(t, directions, distance - self.voxel_m / 2.0)
        cells = self.cells
        flat = cells.reshape(-1)  # a view: writes land in cells
        flat[free[flat[free] < OCCUPIED]] = FREE
        ends = t + directions[hit] * distance[hit, None]
        at = np.floor((ends - self.origin) / self.voxel_m).astype(np.int64)
        inside = np.all((at >= 0) & (at < cells.shape[0]), axis=1)
        plant = np.zeros(int(hit.sum()), bool) if labels is None else labels[v[hit], u[hit]] > 0
        at, plant = at[inside], plant[inside]
        # plant wins over other occupancy: a voxel that holds a leaf's edge and the wall behind
        cells[at[:, 0], at[:, 1], at[:, 2]] = np.maximum(cells[at[:, 0], at[:, 1], at[:, 2]], OCCUPIED)
        cells[at[plant, 0], at[plant, 1], at[plant, 2]] = PLANT
        if self.normals is not None and self.sides is not None and plant.any():
            # the surface's side this view saw, against the normal its voxel first got: a leaf
            # seen from below is its other side, whichever way the views measured its normal
            measured = _depth_normals(camera, depth, u[hit][inside][plant], v[hit][inside][plant]) @ R.T
            i, j, k = at[plant].T
            new = ~self.normals[i, j, k].any(axis=1)
            self.normals[i[new], j[new], k[new]] = measured[new]
            towards = t - ends[inside][plant]
            front = (self.normals[i, j, k] * towards).sum(axis=1) >= 0
            self.sides[i, j, k] |= np.where(front, 1, 2).astype(np.uint8)

    def information_gain(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        rays: tuple[int, int] = (32, 18),
        reach_m: float = 1.5,
        surface: bool = False,
    ) -> int:
        """The unknown voxels a view from ``world_T_camera`` would reach: along a ``rays`` grid of
        its pixels, those met before the first occupied voxel (within ``reach_m``); with
        ``surface``, also the plant voxels first met whose side facing the view is unseen."""
        u = (np.arange(rays[0]) + 0.5) * camera.width / rays[0]
        v = (np.arange(rays[1]) + 0.5) * camera.height / rays[1]
        uu, vv = np.meshgrid(u, v)
        sx, sy = camera.rays(uu.ravel(), vv.ravel())
        slopes = np.column_stack([sx, sy, np.ones_like(sx)])
        directions = (slopes / np.linalg.norm(slopes, axis=1)[:, None]) @ world_T_camera[:3, :3].T
        index, live = self._march(world_T_camera[:3, 3], directions, np.full(len(directions), reach_m))
        n = self.cells.shape[0]
        flat = (index[..., 0] * n + index[..., 1]) * n + index[..., 2]
        state = self.cells.reshape(-1)[flat]
        solid = live & (state >= OCCUPIED)
        blocked = np.logical_or.accumulate(solid, axis=1)
        counted = live & ~blocked & (state == UNKNOWN)
        # each voxel once, however many rays (and samples of one ray) reach it
        reached = np.zeros(self.cells.size, bool)
        reached[flat[counted]] = True
        gain = int(np.count_nonzero(reached))
        if surface and self.normals is not None and self.sides is not None:
            gain += self._unseen_sides(world_T_camera[:3, 3], index, solid)
        return int(gain)

    def _unseen_sides(self, eye: np.ndarray, index: np.ndarray, solid: np.ndarray) -> int:
        """The plant voxels first met by the rays (``index``, ``solid``: R x K) whose side facing
        ``eye`` no view has seen, each once."""
        assert self.normals is not None and self.sides is not None
        ends = solid.any(axis=1)
        first = index[ends, np.argmax(solid[ends], axis=1)]
        i, j, k = first.T
        plant = self.cells[i, j, k] == PLANT
        i, j, k = i[plant], j[plant], k[plant]
        centres = self.origin + (np.column_stack([i, j, k]) + 0.5) * self.voxel_m
        front = (self.normals[i, j, k] * (eye - centres)).sum(axis=1) >= 0
        unseen = (self.sides[i, j, k] & np.where(front, 1, 2)) == 0
        return len(np.unique(np.ravel_multi_index((i[unseen], j[unseen], k[unseen]), self.cells.shape)))

    def counts(self) -> dict[str, int]:
        """How many voxels are unknown, free, occupied (not plant) and plant."""
        c = np.bincount(self.cells.ravel(), minlength=4)
        return {"unknown": int(c[UNKNOWN]), "free": int(c[FREE]), "occupied": int(c[OCCUPIED]), "plant": int(c[PLANT])}


def _depth_normals(camera: CameraModel, depth: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit surface normals (camera frame, facing the camera) at pixels (u, v) of ``depth``,
    from the points of the pixel and its right and lower neighbours (the left and upper ones at
    the image's edge)."""
    h, w = depth.shape

    def point(uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
        sx, sy = camera.rays(uu.astype(np.float64), vv.astype(np.float64))
        z = depth[vv, uu].astype(np.float64)
        return np.column_stack([sx * z, sy * z, z])

    du = np.where(u + 1 < w, 1, -1)
    dv = np.where(v + 1 < h, 1, -1)
    p = point(u, v)
    n = np.cross((point(u + du, v) - p) * du[:, None], (point(u, v + dv) - p) * dv[:, None])
    n *= np.where((n * p).sum(axis=1) > 0, -1.0, 1.0)[:, None]  # towards the camera (at the origin)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
