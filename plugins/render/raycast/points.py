"""Exact ray tracing of a point plant's spheres, beside Open3D's triangles.

Open3D's ``RaycastingScene`` holds triangles only; Mitsuba's ``ellipsoids`` shape holds a
million spheres in one Embree hierarchy (OptiX on a GPU) with a closed-form ray-sphere test,
which is what a point plant needs: the nearest sphere along each ray, and whether a shadow
ray meets any. Its test loses float32 precision for spheres much smaller than its unit (it
starts from a point that is only near the sphere when the sphere's radius is about 1), so the
spheres are traced in a frame whose unit is their radius, centred on the cloud: there the
intersection is exact to about 1e-7 of a radius (measured against a float64 brute force in the
tests).
"""

from __future__ import annotations

import threading

import numpy as np

from agrisim.scene.model import PointSet

F32 = np.float32


class PointTracer:
    """The spheres of ``points`` (diameter ``points.size``), traced exactly."""

    def __init__(self, points: PointSet) -> None:
        from agrisim.plugins.render.mitsuba.variant import use_variant

        if points.size is None:
            raise ValueError("points to trace need a size")
        self.mi = mi = use_variant("auto")
        self.points = points
        self.radius = 0.5 * float(points.size)
        self.origin = 0.5 * (points.positions.min(axis=0) + points.positions.max(axis=0))
        n = len(points)
        centres = ((points.positions - self.origin) / self.radius).astype(F32)
        quaternions = np.zeros((n, 4), F32)
        quaternions[:, 3] = 1.0  # identity (x, y, z, w)
        self.scene = mi.load_dict(
            {
                "type": "scene",
                "points": {
                    "type": "ellipsoids",
                    "centers": mi.TensorXf(centres),
                    "scales": mi.TensorXf(np.ones((n, 3), F32)),
                    "quaternions": mi.TensorXf(quaternions),
                    "extent": 1.0,  # the scale is the radius itself (Mitsuba's default, 3, is for Gaussians)
                },
            }
        )
        self._lock = threading.Lock()  # one Dr.Jit launch at a time; each uses every core

    def _rays(self, rays: np.ndarray, tfar: float | None):  # noqa: ANN202 - Mitsuba's Ray3f
        """Rays (K x 6) in the tracer's frame, with their direction's length (world units per t)."""
        mi = self.mi
        o = (rays[:, :3].astype(np.float64) - self.origin) / self.radius
        d = rays[:, 3:].astype(np.float64)
        length = np.linalg.norm(d, axis=1)
        safe = np.where(length > 0, length, 1.0)
        u = (d / safe[:, None]).astype(F32)
        o = o.astype(F32)
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(u[:, 0], u[:, 1], u[:, 2]))
        if tfar is not None:  # a segment: its length in radii
            ray.maxt = mi.Float((tfar * length / self.radius).astype(F32))
        return ray, length

    def cast(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest sphere along each ray (K x 6: origin, direction): (t in units of the ray's
        direction, inf for a miss; point index, -1 for a miss)."""
        if not len(rays):
            return np.zeros(0, F32), np.zeros(0, np.int64)
        with self._lock:  # every Dr.Jit array made and freed under the lock (a free racing a launch crashed)
            ray, length = self._rays(rays, None)
            hit = self.scene.ray_intersect_preliminary(ray)
            t = np.array(hit.t.numpy(), np.float64)
            index = np.array(hit.prim_index.numpy(), np.int64)
            del hit, ray
        found = np.isfinite(t)
        t = np.where(found, t * self.radius / np.where(length > 0, length, 1.0), np.inf).astype(F32)
        return t, np.where(found, index, -1)

    def occluded(self, rays: np.ndarray, tfar: float) -> np.ndarray:
        """Does each ray (K x 6: origin, segment) meet a sphere within ``tfar`` of its segment?"""
        if not len(rays):
            return np.zeros(0, bool)
        with self._lock:
            ray, _ = self._rays(rays, tfar)
            hit = self.scene.ray_test(ray)
            blocked = np.array(hit.numpy(), bool)
            del hit, ray
        return blocked

    def normals(self, index: np.ndarray, at: np.ndarray) -> np.ndarray:
        """Unit normals (3 x K, float32) of the spheres ``index`` at points ``at`` (3 x K)."""
        n = at.astype(np.float64) - self.points.positions[index].T
        n /= np.maximum(np.linalg.norm(n, axis=0), 1e-12)
        return n.astype(F32)
