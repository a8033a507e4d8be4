"""Which arm links the rays of a view can meet, told by boxes: a link is left out of a cast when
its box lies wholly outside a convex volume that all those rays stay in: the view's frustum for
the camera's rays, the hull of the frustum and the lights' points for shadow rays. Leaving a
link out changes no hit: no ray of the cast can reach it.

Why: on the CPU every link that is cast costs a BVH build a view (Embree rebuilds the shape
groups of a scene whose instances move) and a traversal of its instance by each ray whose path
crosses its box, and the arm holding the camera has every link behind it (issue 44: 4 or 5 of
the 16 links are in view; posing and the arms' cast fall to about half).
"""

from __future__ import annotations

import numpy as np

from agrisim.scene.camera import CameraModel

#: how far outside a plane (m) a box must lie to be left out of the camera's rays: float32
#: round-off of the rays' origins on the near plane, far below any surface
TOLERANCE = 1e-6


def box_corners(vertices: np.ndarray) -> np.ndarray:
    """The 8 corners (8, 3) of the axis-aligned box of ``vertices``."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    return np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])


def frustum_corners(
    camera: CameraModel, world_T_camera: np.ndarray, near: float, far: float, margin_px: float = 1.0
) -> np.ndarray:
    """World corners (8, 3) of the volume the pixel rays sweep from ``near`` to ``far`` (planar
    depth), the image widened by ``margin_px`` on every side (sub-pixel offsets stay inside)."""
    us = np.array([-margin_px, camera.width + margin_px]) - 0.5
    vs = np.array([-margin_px, camera.height + margin_px]) - 0.5
    if camera.pinhole:
        x, y = (us - camera.cx) / camera.fx, (vs - camera.cy) / camera.fy
    else:
        # through a lens the border's rays bound every pixel's (the lens does not fold): their
        # slopes' box, from points along the widened image's four sides
        t = np.linspace(0.0, 1.0, 257)
        u = np.concatenate(
            [us[0] + t * (us[1] - us[0]), np.full_like(t, us[1]), us[0] + t * (us[1] - us[0]), np.full_like(t, us[0])]
        )
        v = np.concatenate(
            [np.full_like(t, vs[0]), vs[0] + t * (vs[1] - vs[0]), np.full_like(t, vs[1]), vs[0] + t * (vs[1] - vs[0])]
        )
        sx, sy = camera.rays(u, v)
        x, y = np.array([sx.min(), sx.max()]), np.array([sy.min(), sy.max()])
    local = np.array([[xi * z, yi * z, z] for z in (near, far) for xi in x for yi in y])
    T = np.asarray(world_T_camera, np.float64)
    return local @ T[:3, :3].T + T[:3, 3]


def hull_planes(points: np.ndarray) -> np.ndarray | None:
    """Outward planes (k, 4: unit normal, offset; ``n . x + d > 0`` outside) of the convex hull
    of ``points``; None when they span no volume (nothing can then be left out safely)."""
    from scipy.spatial import ConvexHull, QhullError  # (here: the GPU's minimal install has no SciPy, nor culls)

    try:
        return ConvexHull(np.asarray(points, np.float64)).equations
    except (QhullError, ValueError):
        return None


def outside(corners: np.ndarray, planes: np.ndarray | None, tolerance: float = TOLERANCE) -> bool:
    """Does the box of ``corners`` lie wholly outside one of ``planes`` (so outside the hull),
    farther than ``tolerance`` (m)?"""
    if planes is None:
        return False
    distance = corners @ planes[:, :3].T + planes[:, 3]  # (8, k)
    return bool((distance > tolerance).all(axis=0).any())
