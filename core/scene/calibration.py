"""A camera's calibration read from the files the field writes (``--camera-calibration``):

* OpenCV's YAML or JSON (``cv::FileStorage``), as OpenCV's calibration sample writes it after
  ``calibrateCamera``: ``image_width``, ``image_height``, ``camera_matrix``,
  ``distortion_coefficients`` and, from ``fisheye::calibrate``, ``fisheye_model: 1``;
* ROS's ``camera_info`` YAML (``camera_calibration``'s output): the same sizes, ``camera_matrix``
  and ``distortion_coefficients`` as ``{rows, cols, data}``, and ``distortion_model``
  (``plumb_bob`` or ``equidistant``).

OpenCV's file parser reads both (plain YAML is YAML to it)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.scene.camera import CameraModel
from agrisim.scene.lens import Distortion

#: ROS's distortion_model names -> agrisim's
ROS_MODELS = {"plumb_bob": "brown-conrady", "equidistant": "fisheye"}


def read_calibration(path: Path) -> CameraModel:
    """The camera a calibration file describes; a UserError naming the problem otherwise."""
    import cv2

    where = f"camera calibration {path}"
    if not path.is_file():
        raise UserError(f"{where}: no such file")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        opened = fs.isOpened()
    except (cv2.error, SystemError) as e:  # (OpenCV's parser raises through SystemError)
        cause = e.__cause__ or e
        message = str(cause).strip().splitlines()[-1] if str(cause).strip() else type(cause).__name__
        raise UserError(f"{where} does not parse as OpenCV YAML/JSON or ROS camera_info: {message}") from None
    if not opened:
        raise UserError(f"{where} does not parse as OpenCV YAML/JSON or ROS camera_info")
    try:
        width, height = _integer(fs, "image_width", where), _integer(fs, "image_height", where)
        K = _matrix(fs, "camera_matrix", where).reshape(3, 3)
        coefficients = _matrix(fs, "distortion_coefficients", where, optional=True).ravel()
        model = _model(fs, coefficients, where)
    finally:
        fs.release()
    if not (
        np.allclose(K[[0, 1, 2, 2], [1, 0, 0, 1]], 0.0) and np.isclose(K[2, 2], 1.0) and K[0, 0] > 0 and K[1, 1] > 0
    ):
        raise UserError(f"{where}: camera_matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
    lens = _lens(model, coefficients, where)
    return CameraModel(width, height, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), lens)


def _integer(fs: Any, key: str, where: str) -> int:
    node = fs.getNode(key)
    if node.empty() or not node.isInt() and not node.isReal():
        raise UserError(f"{where}: no {key} (a whole number of pixels)")
    value = node.real()
    if value != int(value) or not 8 <= value <= 8192:
        raise UserError(f"{where}: {key} must be a whole number of pixels in 8..8192, got {value:g}")
    return int(value)


def _matrix(fs: Any, key: str, where: str, optional: bool = False) -> np.ndarray:
    node = fs.getNode(key)
    if node.empty():
        if optional:
            return np.zeros(0)
        raise UserError(f"{where}: no {key}")
    if node.isMap() and not node.getNode("data").empty():  # ROS's {rows, cols, data}
        data = node.getNode("data")
        values = np.array([data.at(i).real() for i in range(data.size())], np.float64)
    else:
        mat = node.mat()
        if mat is None:
            raise UserError(f"{where}: {key} is not a matrix")
        values = np.asarray(mat, np.float64).ravel()
    if key == "camera_matrix" and values.size != 9:
        raise UserError(f"{where}: camera_matrix must have 9 values, got {values.size}")
    if not np.isfinite(values).all():
        raise UserError(f"{where}: {key} holds a value that is not a finite number")
    return values


def _model(fs: Any, coefficients: np.ndarray, where: str) -> str:
    ros = fs.getNode("distortion_model")
    if not ros.empty():
        name = ros.string()
        if name not in ROS_MODELS:
            raise UserError(f"{where}: distortion_model {name!r} is not supported; allowed: {', '.join(ROS_MODELS)}")
        return ROS_MODELS[name]
    fisheye = fs.getNode("fisheye_model")
    return "fisheye" if not fisheye.empty() and fisheye.real() == 1 else "brown-conrady"


def _lens(model: str, coefficients: np.ndarray, where: str) -> Distortion | None:
    if coefficients.size == 0 or not coefficients.any():
        return None
    c = [float(v) for v in coefficients]
    if model == "fisheye":
        if len(c) != 4:
            raise UserError(f"{where}: a fisheye lens has 4 coefficients (k1, k2, k3, k4), got {len(c)}")
        return Distortion("fisheye", tuple(c))
    if len(c) in (4, 5) or len(c) > 5 and not any(c[5:]):  # (OpenCV's 8/12/14 with the rest 0)
        k1, k2, p1, p2, k3 = (c + [0.0])[:5]
        return Distortion("brown-conrady", (k1, k2, p1, p2, k3))
    raise UserError(
        f"{where}: {len(c)} distortion coefficients with the rational or thin-prism terms set are not supported; "
        "allowed: 4 or 5 (k1, k2, p1, p2[, k3]) or a fisheye's 4"
    )


def ros_distortion(lens: Distortion | dict[str, Any] | None) -> tuple[str, list[float]]:
    """``camera_info``'s ``distortion_model`` and ``D`` for a lens (a :class:`Distortion`, or
    ``cameras.json``'s form of one): ``plumb_bob`` with k1, k2, p1, p2, k3 (a pinhole: five
    zeros), or ``equidistant`` with a fisheye's k1..k4."""
    if isinstance(lens, dict):
        lens = Distortion.from_dict(lens)
    if lens is None:
        return "plumb_bob", [0.0] * 5
    return ("equidistant" if lens.model == "fisheye" else "plumb_bob"), [float(c) for c in lens.coefficients]
