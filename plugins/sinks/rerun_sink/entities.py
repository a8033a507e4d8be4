"""What the recording holds and where: entity paths, timelines, colours and rates, and the
small numeric helpers the sink logs with (numpy only: importing this costs nothing)."""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from agrisim.records import Run

APPLICATION_ID = "agrisim"
#: arm link transforms are logged at this rate of simulated time, Hz
TRANSFORM_RATE = 30.0
#: planned / executed camera paths are drawn with points at this rate, Hz
PATH_RATE = 60.0
#: distance of the image plane drawn for each camera in 3D views, m
IMAGE_PLANE_DISTANCE = 0.08
#: length of the viewing-direction arrows drawn at each setpoint, m
SETPOINT_ARROW = 0.05
RGB_JPEG_QUALITY = 90
#: most points a per-view / merged cloud keeps in the recording (the files on disk keep all)
VIEW_CLOUD_POINTS = 20_000
MERGED_CLOUD_POINTS = 300_000

TIMELINE_SETPOINT = "setpoint"
TIMELINE_SIM_TIME = "sim_time"

ROBOT_COLORS = [(230, 120, 40), (40, 130, 230), (120, 200, 80), (200, 80, 200)]
OBSTACLE_COLORS = {
    "floor": (205, 205, 200, 255),
    "table": (150, 110, 75, 255),
    "pot": (170, 85, 50, 255),
    "plant_keepout": (220, 60, 60, 60),
}
STAND_COLOR = (90, 90, 95, 255)
STATUS_COLORS = {"pending": (160, 160, 160), "reached": (40, 200, 80), "failed": (230, 40, 40)}
#: URDF primitives (the camera body) without a material colour
PRIMITIVE_COLOR = (40, 40, 40, 255)


class paths:  # noqa: N801 - a namespace of path builders, used like a module
    """Entity paths of the recording, in one place."""

    WORLD = "world"
    CELL = "world/cell"
    SETPOINTS = "world/setpoints"
    CLOUDS = "world/clouds"
    #: every view's cloud, per label (``cloud(label, merged=False)``)
    VIEW_CLOUDS = "world/clouds/view"
    #: the merged clouds, per label (``cloud(label, merged=True)``)
    MERGED_CLOUDS = "world/clouds/merged"
    PLANT = "world/plant"
    LIGHTS = "world/lights"
    METRICS = "metrics"
    RUN_CONFIG = "run/config"
    RUN_SUMMARY = "run/summary"
    #: images under each camera: a Frame field -> child entity name
    IMAGE_KINDS = ("rgb", "labels", "depth", "instances")
    #: beside a depth sensor's ``depth``: the exact depth
    DEPTH_TRUTH = "depth_truth"
    #: a bench's: which plant each pixel shows (its annotation context names ``plant_01``...)
    PLANTS = "plants"

    @staticmethod
    def obstacle(name: str) -> str:
        return f"world/cell/{name}"

    @staticmethod
    def scene_mesh(name: str, material: int) -> str:
        """A static scene mesh (room, clutter, pot, the plant), one entity per material."""
        return f"world/scene/{name}/{material}"

    @staticmethod
    def scene_points(name: str) -> str:
        """A point plant as drawn: its spheres."""
        return f"world/scene/{name}/points"

    @staticmethod
    def light(name: str) -> str:
        return f"world/lights/{name}"

    @staticmethod
    def robot(robot: str) -> str:
        return f"world/{robot}"

    @staticmethod
    def link(robot: str, link: str) -> str:
        """The entity whose transform is ``world_T_link``."""
        return f"world/{robot}/{link}"

    @staticmethod
    def link_visual(robot: str, link: str, index: int) -> str:
        """A link's visual geometry (with its static ``link_T_visual``)."""
        return f"world/{robot}/{link}/visual_{index}"

    @staticmethod
    def camera(robot: str) -> str:
        """The camera's optical frame (``world_T_camera``, OpenCV axes) and its ``Pinhole``."""
        return f"world/{robot}/camera"

    @staticmethod
    def camera_image(robot: str, kind: str) -> str:
        """``kind`` is ``rgb``, ``labels``, ``depth`` (a depth sensor's measurement where the run
        has one), ``instances``, ``depth_truth`` (the exact depth, beside a sensor's) or
        ``plants`` (a bench's)."""
        return f"world/{robot}/camera/{kind}"

    @staticmethod
    def planned(robot: str) -> str:
        return f"world/{robot}/planned"

    @staticmethod
    def executed(robot: str) -> str:
        return f"world/{robot}/executed"

    @staticmethod
    def setpoints(robot: str) -> str:
        return f"world/setpoints/{robot}"

    @staticmethod
    def setpoint_views(robot: str) -> str:
        return f"world/setpoints/{robot}/view"

    @staticmethod
    def cloud(label: str, merged: bool) -> str:
        return f"{paths.MERGED_CLOUDS if merged else paths.VIEW_CLOUDS}/{label}"

    @staticmethod
    def metric(robot: str, name: str) -> str:
        return f"metrics/{robot}/{name}"

    @staticmethod
    def log(robot: str) -> str:
        return f"log/{robot}"


def quaternions_xyzw(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) of rotation matrices ``R`` (N x 3 x 3), vectorised.

    Each row uses the largest of the four squared components as the pivot (Shepperd's method),
    which stays accurate for every rotation, 180-degree turns included.
    """
    R = np.asarray(R, float).reshape(-1, 3, 3)
    m00, m11, m22 = R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]
    four = np.stack([1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22, 1 + m00 + m11 + m22], axis=1)
    pivot = np.argmax(four, axis=1)
    s = 2.0 * np.sqrt(np.maximum(four[np.arange(len(R)), pivot], 1e-300))  # = 4 * pivot component
    d21, d02, d10 = R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]
    s01, s02, s12 = R[:, 0, 1] + R[:, 1, 0], R[:, 0, 2] + R[:, 2, 0], R[:, 1, 2] + R[:, 2, 1]
    q = np.empty((len(R), 4))
    cases = [
        np.stack([s / 4, s01 / s, s02 / s, d21 / s], 1),  # x largest
        np.stack([s01 / s, s / 4, s12 / s, d02 / s], 1),  # y largest
        np.stack([s02 / s, s12 / s, s / 4, d10 / s], 1),  # z largest
        np.stack([d21 / s, d02 / s, d10 / s, s / 4], 1),  # w largest
    ]
    for k, case in enumerate(cases):
        q[pivot == k] = case[pivot == k]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def decimate(t: np.ndarray, rate: float) -> np.ndarray:
    """Indices of the samples at times ``t`` (sorted) nearest below each tick of ``rate`` Hz,
    always with the first and last sample."""
    t = np.asarray(t, float)
    if len(t) == 0:
        return np.zeros(0, int)
    ticks = np.arange(t[0], t[-1], 1.0 / rate)
    idx = np.searchsorted(t, ticks, side="left")
    return np.unique(np.concatenate([[0], np.clip(idx, 0, len(t) - 1), [len(t) - 1]]))


def recording_id(run: Run) -> str:
    """A recording id derived from the run (output directory and start time), stable for the
    run so that other processes logging about it land in the same recording."""
    ident = f"agrisim:{Path(run.out_dir).resolve()}:{run.started_at}"
    return str(uuid.uuid5(uuid.NAMESPACE_URL, ident))


def robot_color(run: Run, robot: str) -> tuple[int, int, int]:
    names = list(run.cell.arm_names)
    return ROBOT_COLORS[names.index(robot) % len(ROBOT_COLORS)] if robot in names else (200, 200, 200)


def rgba255(rgba: Sequence[float] | None, default: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    if rgba is None:
        return default
    return tuple(int(round(255 * min(max(c, 0.0), 1.0))) for c in rgba)  # type: ignore[return-value]
