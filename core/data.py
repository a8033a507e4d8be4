"""The data the episode and its backends pass each other: joint trajectories and what executing
them did, rendered frames and captures, views, clouds and reconstructions, imager shots. Plain
dataclasses of numpy arrays (metres, radians, seconds; poses are 4x4 ``a_T_b``); the ABCs that
exchange them are :mod:`agrisim.interfaces`, which serves these names too."""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agrisim.scene.camera import CameraModel
from agrisim.scene.encoding import depth_to_mm, mm_to_depth

__all__ = [
    "Capture",
    "Cloud",
    "Execution",
    "Exposure",
    "Frame",
    "JointTrajectory",
    "Reconstruction",
    "SensorGeometry",
    "Shot",
    "SurfaceMesh",
    "Trajectory",
    "View",
    "view_key",
]


@dataclass
class JointTrajectory:
    """Joint positions ``q`` (N x dof) at times ``t`` (N,), seconds; ``qd`` optional velocities."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray | None = None

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def shifted(self, t0: float) -> JointTrajectory:
        """The same trajectory starting at ``t0``."""
        return JointTrajectory(self.t - self.t[0] + t0, self.q, self.qd)


@dataclass
class Trajectory:
    """One arm's move to a setpoint, as announced by ``agrisim_trajectory``."""

    robot: str
    setpoint: int
    path: np.ndarray  # the planner's collision-checked waypoints (M x dof)
    planned: JointTrajectory  # the time-parametrised path, in run time
    executed: JointTrajectory  # what the physics reports the arm did


@dataclass
class Execution:
    """What a physics backend reports after executing one arm's trajectory."""

    executed: JointTrajectory
    settled: bool  # reached the goal (by the caller's test) before the timeout
    settle_time: float  # seconds after the trajectory's end until settled (or the timeout)
    contacts: list[str] = field(default_factory=list)  # collisions seen while moving, "a|b"


@dataclass
class Frame:
    """One camera's images (OpenCV pixel grid, H x W): the one image type, from the renderer
    through the capture hook to the sinks and the reconstruction."""

    rgb: np.ndarray  # uint8 H x W x 3, sRGB
    labels: np.ndarray  # uint8 H x W, label ids (0 = background)
    depth: np.ndarray  # float32 H x W, planar z in metres, 0 where nothing was hit
    instances: np.ndarray | None = None  # uint16 H x W leaf instance ids, 0 = none
    #: float32 H x W x 3 linear RGB radiance before exposure and tone mapping, from renderers
    #: asked to keep it (the dataset writes it as ``radiance/<frame>.exr``)
    radiance: np.ndarray | None = None
    #: float32 H x W planar depth in metres on these pixels as the run's depth sensor measured
    #: it (:class:`DepthSensor`; 0 where it gave none), or None when the sensor is exact
    depth_sensor: np.ndarray | None = None
    #: uint16 H x W raw Bayer frame (digital numbers, black level included) that an imager
    #: developed ``rgb`` from, when the run keeps it (``raw/<frame>.png``)
    raw: np.ndarray | None = None
    #: uint16 H x W: which plant of a bench each pixel shows (k: ``Scene.bench[k - 1]``; 0: none)
    plants: np.ndarray | None = None
    # depth_mm's answer, kept: the dataset writer, the recording and the reconstruction all ask
    _depth_mm: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    def depth_mm(self) -> np.ndarray:
        """Depth as the dataset's PNGs store it: uint16 whole millimetres, 0 = no hit (computed
        once; do not write into the answer)."""
        if self._depth_mm is None or self._depth_mm.shape != np.shape(self.depth):
            self._depth_mm = depth_to_mm(self.depth)
        return self._depth_mm

    def stored(self, exact_depth: bool = False) -> Frame:
        """These images as they read back from the run directory: depth rounded to whole
        millimetres (float32 metres, as Open3D reads the PNG with ``depth_scale = 1000``), or
        as it is where the dataset keeps it exactly (EXR), so that a run, its ``--resume`` and
        ``agrisim recon`` integrate bit-identical data."""
        depth = np.asarray(self.depth, np.float32) if exact_depth else mm_to_depth(self.depth_mm())
        sensed = None if self.depth_sensor is None else mm_to_depth(depth_to_mm(self.depth_sensor))
        return dataclasses.replace(self, depth=depth, depth_sensor=sensed)

    def with_depth(self, source: str) -> Frame:
        """These images with the depth that ``source`` names: ``truth`` (as they are) or
        ``sensor`` (the sensor's measurement in place of the exact depth; as they are when the
        sensor is exact)."""
        if source == "truth" or self.depth_sensor is None:
            return self
        return dataclasses.replace(self, depth=self.depth_sensor)

    def copy(self) -> Frame:
        """A deep copy (the arrays too)."""
        fields = (f.name for f in dataclasses.fields(self) if f.init)
        return Frame(**{name: None if (a := getattr(self, name)) is None else a.copy() for name in fields})  # type: ignore[arg-type]


@dataclass
class Capture:
    """A camera's capture at a reached setpoint (``agrisim_capture``); ``images`` is the
    renderer's :class:`Frame`, or None when the run has no renderer."""

    robot: str
    frame: str  # r1_000 ... r2_049
    setpoint: int
    sim_time: float
    world_T_camera: np.ndarray
    camera: CameraModel
    images: Frame | None = None
    #: a frame already complete on disk from before ``--resume``: replayed, not rendered
    replayed: bool = False
    #: ``world_T_link`` of every arm link (robot -> link -> 4x4) the frame was rendered with
    link_poses: dict[str, dict[str, np.ndarray]] | None = None
    #: the imager's exposure of this frame (time_s, analogue_gain, metered_luminance), when the
    #: run has an imager
    exposure: dict[str, float] | None = None


@dataclass(frozen=True)
class SensorGeometry:
    """Where a depth sensor sits beside the colour camera and what its imager sees."""

    camera: CameraModel
    """The sensor's own pinhole model: its image size and intrinsics (OpenCV)."""
    camera_T_sensor: np.ndarray
    """4 x 4 pose of the sensor's optical frame in the colour camera's (OpenCV axes, metres)."""


@dataclass
class View:
    """One camera's images at one setpoint with its pose, as reconstruction sees them: the
    images are :meth:`Frame.stored` (depth in whole millimetres), whether they come straight
    from the renderer or are read back from the run directory."""

    frame: str
    camera: CameraModel
    world_T_camera: np.ndarray  # 4x4, OpenCV optical frame
    images: Frame


@dataclass
class Cloud:
    """A coloured point cloud in world coordinates."""

    points: np.ndarray  # (N, 3) float64, metres
    colors: np.ndarray  # (N, 3) uint8 sRGB

    def __len__(self) -> int:
        return len(self.points)


@dataclass
class SurfaceMesh:
    """A coloured triangle mesh in world coordinates (a reconstructed surface)."""

    vertices: np.ndarray  # (N, 3) float64, metres
    triangles: np.ndarray  # (M, 3) int32
    colors: np.ndarray | None = None  # (N, 3) uint8 per vertex


@dataclass
class Reconstruction:
    """What a reconstructor built, per label name, plus ``"all"`` (every plant label together):
    ``clouds`` go to ``clouds/<label>.ply``, ``meshes`` to ``clouds/<label>_mesh.ply``."""

    clouds: dict[str, Cloud] = field(default_factory=dict)
    meshes: dict[str, SurfaceMesh] = field(default_factory=dict)
    #: the reconstructor's own measurements, written into ``metrics.json`` under its name
    metrics: dict[str, Any] = field(default_factory=dict)
    #: the reconstructor's own files, path relative to the run directory (inside the folder its
    #: capabilities declare) -> contents, each written atomically
    files: dict[str, bytes] = field(default_factory=dict)


@dataclass(frozen=True)
class Exposure:
    """One shot's exposure: time and analogue gain, and the mean luminance it metered."""

    time_s: float
    gain: float
    metered: float = float("nan")

    @property
    def total(self) -> float:
        return self.time_s * self.gain

    def to_json(self) -> dict[str, float]:
        return {"time_s": self.time_s, "analogue_gain": self.gain, "metered_luminance": self.metered}

    @classmethod
    def from_json(cls, doc: dict[str, float]) -> Exposure:
        return cls(float(doc["time_s"]), float(doc["analogue_gain"]), float(doc.get("metered_luminance", "nan")))


@dataclass
class Shot:
    """What an imager made of one view: the developed 8-bit RGB, the raw frame it came from
    (uint16 digital numbers) and the exposure."""

    rgb: np.ndarray
    raw: np.ndarray
    exposure: Exposure


def view_key(frame: str) -> int:
    """The number that seeds a view's noise beside the run's seed (its frame name's CRC-32): the
    same frame gets the same noise in a run, its ``--resume`` and ``agrisim render``."""
    return zlib.crc32(frame.encode())
