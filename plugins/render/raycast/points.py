"""Exact ray tracing of a point plant's spheres, in the same Dr.Jit kernels as the triangles.

Mitsuba's ``ellipsoids`` shape holds a million spheres in one Embree hierarchy (OptiX on a
GPU) with a closed-form ray-sphere test, which is what a point plant needs: the nearest sphere
along each ray, and whether a shadow ray meets any. Its test loses float32 precision for
spheres much smaller than its unit (it starts from a point that is only near the sphere when
the sphere's radius is about 1), so the spheres are traced in a frame whose unit is their
radius, centred on the cloud, with rays carried there in float64: there the intersection is
exact to about 1e-7 of a radius (measured against a float64 brute force in the tests).
"""

from __future__ import annotations

from typing import Any

import drjit as dr
import numpy as np

from agrisim.scene.model import PointSet

F32 = np.float32


class PointTracer:
    """The spheres of ``points`` (diameter ``points.size``), traced exactly with Mitsuba ``mi``
    (set to its variant), on Dr.Jit arrays; :meth:`cast` and :meth:`occluded` take numpy rays."""

    def __init__(self, points: PointSet, mi: Any = None) -> None:
        if points.size is None:
            raise ValueError("points to trace need a size")
        if mi is None:
            from agrisim.plugins.render.mitsuba.variant import use_variant

            mi = use_variant("auto")
        self.mi = mi
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
        self.positions = mi.Float(np.ascontiguousarray(points.positions, F32).reshape(-1))
        self.labels = mi.UInt32(points.labels.astype(np.uint32))
        self.instances = mi.UInt32(points.instances.astype(np.uint32)) if points.instances is not None else None
        self.colors = mi.UInt32(points.colors.astype(np.uint32).reshape(-1))

    def _ray(self, o: Any, d: Any, tfar: float | None) -> tuple[Any, Any]:
        """The ray (origins ``o``, directions ``d``) in the spheres' frame, and its direction's
        length (world units per t)."""
        mi = self.mi
        o64 = mi.Vector3d(o) - mi.Vector3d(self.origin)
        d64 = mi.Vector3d(d)
        length = dr.norm(d64)
        safe = dr.select(length > 0, length, 1.0)
        ray = mi.Ray3f(mi.Point3f(o64 / self.radius), mi.Vector3f(d64 / safe))
        if tfar is not None:  # a segment: its length in radii
            ray.maxt = mi.Float(tfar * length / self.radius)
        return ray, length

    def cast_dr(self, o: Any, d: Any, active: Any = True) -> tuple[Any, Any]:
        """Nearest sphere along each ray: (Float t in units of the ray's direction, inf for a
        miss; Int32 point index, -1 for a miss)."""
        mi = self.mi
        ray, length = self._ray(o, d, None)
        pi = self.scene.ray_intersect_preliminary(ray, coherent=False, active=active)
        found = active & pi.is_valid()
        t = mi.Float(mi.Float64(pi.t) * self.radius / dr.select(length > 0, length, 1.0))
        return dr.select(found, t, dr.inf), dr.select(found, mi.Int32(pi.prim_index), -1)

    def occluded_dr(self, o: Any, seg: Any, tfar: float, active: Any = True) -> Any:
        """Bool: does each ray (origin, segment) meet a sphere within ``tfar`` of its segment?"""
        ray, _ = self._ray(o, seg, tfar)
        return self.scene.ray_test(ray, active)

    def normal_dr(self, index: Any, p: Any, active: Any = True) -> Any:
        """Vector3f unit normals of the spheres ``index`` at points ``p``."""
        mi = self.mi
        i = mi.UInt32(dr.maximum(index, 0)) * 3
        centre = mi.Vector3f(*(dr.gather(mi.Float, self.positions, i + k, active) for k in range(3)))
        return dr.normalize(p - centre)

    def color_dr(self, index: Any, active: Any = True) -> Any:
        """UInt32 sRGB bytes (r, g, b) of the points ``index``."""
        mi = self.mi
        i = mi.UInt32(dr.maximum(index, 0)) * 3
        return tuple(dr.gather(mi.UInt32, self.colors, i + k, active) for k in range(3))

    # numpy in and out, for tests and tools
    def cast(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest sphere along each ray (K x 6: origin, direction): (t in units of the ray's
        direction, inf for a miss; point index, -1 for a miss)."""
        if not len(rays):
            return np.zeros(0, F32), np.zeros(0, np.int64)
        o, d = _vectors(self.mi, rays)
        t, index = self.cast_dr(o, d)
        return np.asarray(t, F32), np.asarray(index, np.int64)

    def occluded(self, rays: np.ndarray, tfar: float) -> np.ndarray:
        """Does each ray (K x 6: origin, segment) meet a sphere within ``tfar`` of its segment?"""
        if not len(rays):
            return np.zeros(0, bool)
        o, d = _vectors(self.mi, rays)
        return np.asarray(self.occluded_dr(o, d, tfar), bool)


def _vectors(mi: Any, rays: np.ndarray) -> tuple[Any, Any]:
    r = np.ascontiguousarray(rays, F32)
    return mi.Point3f(*(r[:, j] for j in range(3))), mi.Vector3f(*(r[:, 3 + j] for j in range(3)))
