"""A captured view as reconstruction and metrics see it, and its back-projection.

Reconstruction works from the images *as the dataset stores them* (depth in whole millimetres),
whether the view comes straight from the renderer or is read back from disk: a run, its
``--resume`` and ``agrisim recon RUN_DIR`` then integrate bit-identical data and give identical
clouds and metrics. Back-projection follows the paper's Eq. 1 and OpenCV's pixel grid (pixel
(u, v) is the image point (u, v)), exactly as Open3D's ``create_from_rgbd_image`` does.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image

from agrisim.errors import UserError
from agrisim.files import layout
from agrisim.files.exr import read_exr
from agrisim.interfaces import CameraModel, Capture, Frame, View
from agrisim.scene.encoding import mm_to_depth
from agrisim.scene.lens import Distortion


def view_from_capture(capture: Capture, exact_depth: bool = False, depth: str = "truth") -> View:
    """The view of a freshly rendered capture, with depth as the dataset stores it: rounded to
    millimetres, or exact where the run keeps EXR depth; ``depth`` = ``sensor`` puts what the
    depth sensor measured in its place (:meth:`Frame.with_depth`)."""
    assert capture.images is not None, "a capture without images has no view"
    return View(
        capture.frame,
        capture.camera,
        np.asarray(capture.world_T_camera, float),
        capture.images.stored(exact_depth).with_depth(depth),
    )


def view_of(capture: Capture, depth: str = "truth") -> View:
    """The view of a capture whose images were read back from the run directory (already as
    stored), with the depth ``depth`` names."""
    assert capture.images is not None, "a capture without images has no view"
    return View(
        capture.frame, capture.camera, np.asarray(capture.world_T_camera, float), capture.images.with_depth(depth)
    )


def _read_png(path: Path, what: str) -> np.ndarray:
    try:
        with Image.open(path) as im:
            return np.array(im)
    except FileNotFoundError:
        raise UserError(f"missing {what} image {path}: the run's frames are incomplete") from None
    except OSError as exc:
        raise UserError(f"cannot read {what} image {path}: {exc}") from None


def load_depth(run_dir: Path, frame: str) -> np.ndarray:
    """A frame's planar depth in metres (0 = nothing hit): the exact EXR where the run kept it,
    else the PNG's millimetres."""
    exr = layout.depth_exr(run_dir, frame)
    if exr.is_file():
        return read_exr(exr)
    return mm_to_depth(_read_png(layout.image(run_dir, "depth", frame), "depth").astype(np.uint16))


def load_frame(run_dir: Path, frame: str, camera: CameraModel) -> Frame:
    """A frame's images on disk (``rgb/``, ``labels/``, ``depth/`` as EXR if there, else PNG,
    ``instances/``, ``plants/`` and ``depth_sensor/`` where the run has them)."""
    rgb = _read_png(layout.image(run_dir, "rgb", frame), "rgb")
    labels = _read_png(layout.image(run_dir, "labels", frame), "labels")
    depth = load_depth(run_dir, frame)
    shape = (camera.height, camera.width)
    if rgb.shape[:2] != shape or labels.shape != shape or depth.shape != shape:
        raise UserError(f"frame {frame} in {run_dir} is not {camera.width}x{camera.height} as cameras.json says")
    if rgb.ndim == 3 and rgb.shape[2] == 4:
        rgb = rgb[..., :3]
    instances = None
    path = layout.image(run_dir, "instances", frame)
    if path.exists():
        instances = _read_png(path, "instances").astype(np.uint16)
    sensed = None
    path = layout.image(run_dir, layout.DEPTH_SENSOR, frame)
    if path.exists():
        sensed = mm_to_depth(_read_png(path, "depth_sensor").astype(np.uint16))
    path = layout.image(run_dir, layout.PLANTS, frame)
    plants = _read_png(path, "plants").astype(np.uint16) if path.exists() else None
    return Frame(rgb, labels.astype(np.uint8), depth, instances, depth_sensor=sensed, plants=plants)


def load_view(run_dir: Path, frame: str, camera: CameraModel, world_T_camera: np.ndarray, depth: str = "truth") -> View:
    """A frame of a dataset on disk (:func:`load_frame`) as a view, with the depth ``depth``
    names (``truth``, or ``sensor``: ``depth_sensor/`` where the run has it)."""
    images = load_frame(run_dir, frame, camera).with_depth(depth)
    return View(frame, camera, np.asarray(world_T_camera, float), images)


def backproject(view: View, mask: np.ndarray, max_depth: float) -> tuple[np.ndarray, np.ndarray]:
    """World points (N x 3, float64) and their colours (N x 3 uint8) of the pixels in ``mask``
    with a depth in (0, ``max_depth``] (the paper drops depth > 1 m).

    Pixels are taken in row-major order, as Open3D orders the points of
    ``PointCloud.create_from_rgbd_image``.
    """
    # gather first, convert only the kept pixels: a full-frame float image costs more than the
    # back-projection itself at 1080p
    depth = view.images.depth  # float32 metres from whole millimetres, as Open3D reads the PNG
    v, u = np.nonzero(mask & (depth > 0))
    z32 = depth[v, u]
    near = z32 <= np.float32(max_depth)
    v, u, z = v[near], u[near], z32[near].astype(np.float64)
    cam = view.camera
    if cam.pinhole:
        x = (u - cam.cx) * z / cam.fx
        y = (v - cam.cy) * z / cam.fy
    else:  # each pixel along its own ray through the lens; z is still the depth along the axis
        sx, sy = cam.rays(u.astype(np.float64), v.astype(np.float64))
        x, y = sx * z, sy * z
    T = view.world_T_camera
    points = np.column_stack([x, y, z]) @ T[:3, :3].T + T[:3, 3]
    return points, view.images.rgb[v, u]


def as_pinhole(view: View) -> View:
    """``view`` through a lens resampled onto the pinhole of its ``K`` (OpenCV's undistortion
    maps): each pinhole pixel takes the lens pixel nearest where its ray lands, so labels,
    depth (still z along the axis: the same surface point) and instances keep their values;
    RGB is interpolated bilinearly. Pixels whose ray falls outside the lens image are empty. For
    reconstructors that read pinholes (Open3D's TSDF). A pinhole view is returned as it is."""
    cam = view.camera
    if cam.pinhole:
        return view
    import cv2

    map_x, map_y = _undistortion_maps(cam)
    images = view.images

    def nearest(image: np.ndarray | None) -> np.ndarray | None:
        if image is None:
            return None
        return cv2.remap(image, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    rgb = cv2.remap(images.rgb, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    pinhole = CameraModel(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
    frame = Frame(
        rgb,
        nearest(images.labels),  # type: ignore[arg-type]
        nearest(images.depth),  # type: ignore[arg-type]
        nearest(images.instances),
        None,
        nearest(images.depth_sensor),
    )
    return View(view.frame, pinhole, view.world_T_camera, frame)


def _undistortion_maps(camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Where each pixel of ``camera``'s pinhole lands in its lens image (float32 maps; made
    once per camera, not per view)."""
    assert camera.distortion is not None
    c = camera
    return _maps(c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.distortion)


@lru_cache(maxsize=2)
def _maps(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, lens: Distortion
) -> tuple[np.ndarray, np.ndarray]:
    import cv2

    K, D, size = CameraModel(width, height, fx, fy, cx, cy).K, lens.opencv, (width, height)
    if lens.model == "fisheye":
        return cv2.fisheye.initUndistortRectifyMap(K, D, np.eye(3), K, size, cv2.CV_32FC1)
    return cv2.initUndistortRectifyMap(K, D, np.eye(3), K, size, cv2.CV_32FC1)
