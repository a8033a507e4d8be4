"""A depth sensor's image moved onto the colour camera's pixels, as librealsense's ``align`` and
the Azure Kinect SDK's depth-to-colour transformation do it.

Each valid depth pixel is a small square of the surface at its depth: its four corners are
lifted to 3D, moved into the colour camera's frame and projected; every colour pixel whose
centre falls inside that footprint's bounding box takes the point's depth, the nearest one where
footprints overlap (the SDK's z-buffer). Colour pixels no depth pixel covers stay 0: outside the
sensor's field of view, and the occlusion holes beside depth edges where the colour camera sees
a surface the depth camera does not. The depth written is planar z in the colour camera's frame,
so that back-projecting it with the colour intrinsics gives the measured point.
"""

from __future__ import annotations

import numpy as np

from agrisim.scene.camera import CameraModel

#: the widest footprint, in colour pixels per side, that one depth pixel may cover (a footprint
#: wider than this is a surface seen edge-on from the colour camera: left as a hole)
MAX_FOOTPRINT = 8


def align_to_colour(
    depth: np.ndarray, sensor: CameraModel, colour: CameraModel, colour_T_sensor: np.ndarray
) -> np.ndarray:
    """``depth`` (float32 H x W planar metres on ``sensor``'s pixels, 0 = none) as planar depth
    on ``colour``'s pixels (float32, 0 = none), the sensor at ``colour_T_sensor``."""
    v, u = np.nonzero(depth > 0)
    z = depth[v, u].astype(np.float64)
    T = np.asarray(colour_T_sensor, np.float64)
    out = np.full(colour.height * colour.width, np.inf)
    if len(z) == 0:
        return np.zeros((colour.height, colour.width), np.float32)
    # the footprint's corners, lifted at the pixel's depth and projected into the colour camera
    xs, ys, zc = [], [], []
    for du, dv in ((-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)):
        p = np.column_stack([(u + du - sensor.cx) / sensor.fx * z, (v + dv - sensor.cy) / sensor.fy * z, z])
        q = p @ T[:3, :3].T + T[:3, 3]
        ok = q[:, 2] > 1e-6
        zq = np.where(ok, q[:, 2], np.nan)
        x, y = colour.project(q[:, 0] / zq, q[:, 1] / zq)  # (through the colour camera's lens, if it has one)
        xs.append(x)
        ys.append(y)
        zc.append(zq)
    with np.errstate(invalid="ignore"):
        x0, x1 = np.ceil(np.min(xs, axis=0)), np.floor(np.max(xs, axis=0))
        y0, y1 = np.ceil(np.min(ys, axis=0)), np.floor(np.max(ys, axis=0))
    # the depth of the pixel's centre, in the colour frame
    centre = np.column_stack([(u - sensor.cx) / sensor.fx * z, (v - sensor.cy) / sensor.fy * z, z])
    depth_c = (centre @ T[:3, :3].T + T[:3, 3])[:, 2]
    keep = (
        np.isfinite(x0 + x1 + y0 + y1)
        & (x1 >= x0)
        & (y1 >= y0)
        & (x1 - x0 < MAX_FOOTPRINT)
        & (y1 - y0 < MAX_FOOTPRINT)
        & (x1 >= 0)
        & (y1 >= 0)
        & (x0 <= colour.width - 1)
        & (y0 <= colour.height - 1)
        & (depth_c > 0)
    )
    x0, x1, y0, y1, depth_c = x0[keep], x1[keep], y0[keep], y1[keep], depth_c[keep]
    if len(depth_c) == 0:
        return np.zeros((colour.height, colour.width), np.float32)
    index, value = [], []
    for dy in range(int((y1 - y0).max()) + 1):  # (footprints span a few colour pixels: few passes)
        for dx in range(int((x1 - x0).max()) + 1):
            x, y = x0 + dx, y0 + dy
            on = (x <= x1) & (y <= y1) & (x >= 0) & (y >= 0) & (x < colour.width) & (y < colour.height)
            index.append((y[on] * colour.width + x[on]).astype(np.int64))
            value.append(depth_c[on])
    index_all, value_all = np.concatenate(index), np.concatenate(value)
    # the z-buffer: footprints overlap only across depth edges, so write them all (one of the
    # overlapping ones wins), then let the nearer ones that lost take their pixels
    out[index_all] = value_all
    lost = out[index_all] > value_all
    np.minimum.at(out, index_all[lost], value_all[lost])
    out[~np.isfinite(out)] = 0.0
    return out.reshape(colour.height, colour.width).astype(np.float32)
