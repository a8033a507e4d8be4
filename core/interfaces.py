"""The contracts between the episode and its backends.

Small ABCs: the episode talks to backends only through these. The data passed between them
(:mod:`agrisim.data`: plain dataclasses of numpy arrays) are served here too.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agrisim.data import (
    Capture,
    Cloud,
    Execution,
    Exposure,
    Frame,
    JointTrajectory,
    Reconstruction,
    SensorGeometry,
    Shot,
    SurfaceMesh,
    Trajectory,
    View,
    view_key,
)
from agrisim.errors import PlanningFailed
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import BenchPlant, LabelTable, Mesh, Plant, Scene

if TYPE_CHECKING:
    from agrisim.config import CellConfig, PlantFileConfig, RenderConfig, RoutineConfig
    from agrisim.robot.cell import Cell
    from agrisim.robot.setpoints import Setpoint

__all__ = [
    "ALL",
    "Bridge",
    "Capture",
    "Cloud",
    "DepthSensor",
    "Execution",
    "Exporter",
    "Exposure",
    "Frame",
    "Imager",
    "JointTrajectory",
    "PhysicsBackend",
    "Planner",
    "PlanningFailed",
    "PlantReader",
    "PlantSpecies",
    "PoseSource",
    "Reconstruction",
    "Reconstructor",
    "Renderer",
    "Rig",
    "Room",
    "SensorGeometry",
    "Shot",
    "SurfaceMesh",
    "Trajectory",
    "Validity",
    "View",
    "view_key",
]

Validity = Callable[[np.ndarray], bool]

#: The name under which a reconstructor gives every labelled point together, beside one entry
#: per label.
ALL = "all"


# ---------------------------------------------------------------------------- backends


class PhysicsBackend(ABC):
    """Simulates the cell: arms, stands, table, pot. Answers collision queries for planners."""

    def __init__(self, cell: Cell, options: Any) -> None:
        self.cell = cell
        self.options = options

    @abstractmethod
    def in_collision(self, robot: str, q: np.ndarray, others: Mapping[str, np.ndarray] | None = None) -> bool:
        """Is ``robot`` at ``q`` in collision with itself, the cell, or the other arms?
        ``others`` gives other arms' configurations; arms not named stay where they are."""

    def arms_in_collision(self, configs: Mapping[str, np.ndarray]) -> bool:
        """Do the arms at ``configs`` touch each other? (Each arm's own path is already checked
        against the cell; this is the cheaper question asked along simultaneous motions.)
        Backends with a faster arm-against-arm test override this."""
        names = list(configs)
        return any(self.in_collision(a, configs[a], {b: configs[b] for b in names if b != a}) for a in names[:1])

    @abstractmethod
    def joint_positions(self, robot: str) -> np.ndarray:
        """The arm's current joint positions."""

    @abstractmethod
    def reset(self, robot: str, q: np.ndarray) -> None:
        """Place the arm at ``q`` at rest (no simulated motion)."""

    @abstractmethod
    def execute(
        self,
        plans: Mapping[str, JointTrajectory],
        settled: Callable[[str, np.ndarray], bool],
        timeout: float,
    ) -> dict[str, Execution]:
        """Run the arms' trajectories together from the current simulated time.

        Each trajectory's ``t`` starts at 0. After its end an arm holds its last position until
        ``settled(robot, q)`` holds or ``timeout`` seconds of simulated time pass."""

    @property
    @abstractmethod
    def sim_time(self) -> float:
        """Simulated seconds since the backend was built."""

    def close(self) -> None:  # noqa: B027 - optional hook for backends holding resources
        """Release resources (connections, files)."""


class Planner(ABC):
    """Finds a collision-free joint path between two configurations."""

    def __init__(self, options: Any) -> None:
        self.options = options

    @abstractmethod
    def plan(
        self,
        start: np.ndarray,
        goal: np.ndarray,
        is_valid: Validity,
        lower: np.ndarray,
        upper: np.ndarray,
        seed: int,
        resolution: float,
    ) -> np.ndarray:
        """Waypoints (M x dof, first = start, last = goal) whose straight segments are valid
        when checked every ``resolution`` radians (see :mod:`agrisim.robot.segments`).

        Raises :class:`PlanningFailed` when there is none within the planner's budget."""


class Renderer(ABC):
    """Draws the scene and the arms (at the poses it is given) through a pinhole camera.

    Built once per run as ``factory(scene, cell, settings, options)``: ``scene`` is the
    :class:`agrisim.scene.model.Scene` (room, plant, lights, label table), ``cell`` gives the arms'
    URDFs (their visual meshes), ``settings`` the run-wide :class:`agrisim.config.RenderConfig`
    (segmentation mode, shadow samples, ...) and ``options`` the backend's own options."""

    def __init__(self, scene: Scene, cell: Cell, settings: RenderConfig, options: Any) -> None:
        self.scene = scene
        self.cell = cell
        self.settings = settings
        self.options = options

    @abstractmethod
    def render(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> Frame:
        """RGB, labels and depth for ``camera`` at ``world_T_camera`` (OpenCV optical frame);
        ``link_poses[robot][link]`` is ``world_T_link`` of every arm link right now."""

    def render_rgb(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """(RGB, radiance): the RGB alone (H x W x 3 uint8), byte for byte :meth:`render`'s, and
        the linear radiance it was encoded from when the renderer keeps it (else None), for
        re-rendering a saved run (``agrisim render``: its labels and depth are kept). Renderers
        that declare the ``rerender`` capability implement it; ``cell`` may then be None, the
        arms coming with the scene (:attr:`Scene.arms`)."""
        raise NotImplementedError(f"{type(self).__name__} does not render RGB alone")

    def render_rgb_stream(
        self,
        camera: CameraModel,
        views: Iterable[tuple[np.ndarray, Mapping[str, Mapping[str, np.ndarray]]]],
    ) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
        """:meth:`render_rgb` of each ``(world_T_camera, link_poses)`` of ``views``, in order,
        as each is ready. A renderer on a GPU may start the next view before handing over this
        one (the host's read-back and encoding then overlap the GPU's work); the images are
        :meth:`render_rgb`'s, byte for byte. ``views`` is read one view ahead at most."""
        for world_T_camera, link_poses in views:
            yield self.render_rgb(camera, world_T_camera, link_poses)

    def arm_meshes(self) -> dict[str, list[tuple[str, Mesh]]]:
        """The arms' visual meshes as this renderer draws them (robot -> (link, mesh in the
        link's frame)), saved with the run's scene so that ``agrisim render`` draws the same
        arms; empty when it draws none or cannot say."""
        return {}

    def close(self) -> None:  # noqa: B027 - optional hook for backends holding resources
        """Release resources."""


class DepthSensor(ABC):
    """A depth camera mounted with the colour camera: what the device measures of the scene,
    as planar depth on the colour camera's pixels (its depth aligned to colour, as
    librealsense's ``align`` and the Azure Kinect SDK's transformation give it).

    Built once per run as ``factory(scene, cell, settings, options)``, like a renderer (the
    sensor casts its own rays into the same scene); the exact sensor measures what the renderer
    drew and returns None."""

    def __init__(self, scene: Scene, cell: Cell | None, settings: RenderConfig, options: Any) -> None:
        self.scene = scene
        self.cell = cell
        self.settings = settings
        self.options = options

    @abstractmethod
    def geometry(self, camera: CameraModel) -> SensorGeometry | None:
        """The sensor's imager and its pose against the colour ``camera``; None: the colour
        camera's own pixels, exactly (the exact sensor)."""

    @abstractmethod
    def measure(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
        frame: Frame,
    ) -> np.ndarray | None:
        """What the sensor measures when the colour ``camera`` is at ``world_T_camera`` and
        the arms at ``link_poses``: float32 H x W planar depth on the colour camera's pixels,
        metres, 0 where the device gives none; None when it is ``frame.depth`` exactly."""

    def close(self) -> None:  # noqa: B027 - optional hook for backends holding resources
        """Release resources."""


class Reconstructor(ABC):
    """Fuses views into a 3D reconstruction per label, one view at a time.

    Built once per run as ``factory(labels, options)``: ``labels`` is the run's
    :class:`agrisim.scene.model.LabelTable`; every non-background label is reconstructed on its own and
    all of them together as ``"all"``. Views arrive as :class:`View` (images as the
    dataset stores them), in capture order."""

    def __init__(self, labels: LabelTable, options: Any) -> None:
        self.labels = labels
        self.options = options

    @abstractmethod
    def integrate(self, view: View) -> dict[str, Cloud]:
        """Add one view; returns the view's own cloud per label name (what it saw)."""

    @abstractmethod
    def merged(self) -> dict[str, Cloud]:
        """The merged cloud so far per label name and ``"all"`` (for streaming to sinks)."""

    @abstractmethod
    def result(self) -> Reconstruction:
        """The final reconstruction of every view integrated so far."""


class Imager(ABC):
    """A colour camera's sensor and image processing: what it makes of each view's linear
    radiance (``[imager] model``, ``--imager``). Each arm's camera has its own, built by
    ``factory(settings: ImagerConfig, seed: int, options)``: the run's ``[imager]`` settings
    (light level, exposure, gain, ...) and its seed, which seeds the noise."""

    @abstractmethod
    def shoot(self, radiance: np.ndarray, view: int) -> Shot:
        """One view's shot of ``radiance`` (H x W x 3 linear sRGB, 1 = a white Lambertian
        surface under irradiance 1), its noise seeded by the run's seed and ``view``
        (:func:`view_key` of the frame): the same pair gives the same bytes."""

    @abstractmethod
    def resume_from(self, exposure: Exposure) -> None:
        """Go on from a shot taken before (``--resume``): the next auto-exposure starts there."""

    @abstractmethod
    def at_exposure(self, exposure: Exposure) -> Imager:
        """This imager at a fixed ``exposure`` (a frame shot again as it was: ``agrisim render``)."""

    @abstractmethod
    def describe(self) -> dict[str, Any]:
        """Its figures and settings, for the run's record (``run.json``, ``cameras.json``)."""


class PlantReader(ABC):
    """Reads the plant files of one format (``--plant FILE``): the first installed reader that
    claims a path reads it, as pytest's collectors claim files (third parties' readers are asked
    before agrisim's own). Built by ``factory(options)``."""

    #: the file suffixes it claims (lower case, with the dot), for :meth:`claims` and messages
    suffixes: tuple[str, ...] = ()
    #: what its files hold: ``mesh`` (a surface) or ``point cloud`` (drawn as points)
    holds: str = "mesh"

    def claims(self, path: Path) -> bool:
        """Whether it reads ``path`` (by default: by its suffix; it need not exist yet)."""
        return path.suffix.lower() in self.suffixes

    @abstractmethod
    def read(self, path: Path, settings: PlantFileConfig, *, place: bool = True) -> Plant:
        """The plant in ``path``, read as the run's ``[plant_file]`` settings say (up axis,
        scale, labels, the root it must lie in), moved into the plant frame (lowest point at
        z = 0, centred in x and y) unless ``place`` is False. Bad input raises
        :class:`agrisim.errors.UserError` naming the file and the problem."""


class PoseSource(ABC):
    """Where a reconstruction's camera poses come from instead of the simulator's
    (``recon.poses``; ``truth``: the simulator's own): an estimate from a finished run's views,
    aligned to the world. Built by ``factory(options)`` when ``agrisim recon`` reads a run."""

    @abstractmethod
    def poses(self, run_dir: Path) -> dict[str, np.ndarray]:
        """The estimated ``world_T_camera`` (4 x 4, OpenCV cameras, metres) of the run's views,
        by frame: only the views it placed. Raises :class:`agrisim.errors.UserError` saying what
        to do where it has none for this run."""


class Room(ABC):
    """What surrounds the robot cell (``[room] backend``): the room, what the cell's obstacles
    look like, the lights. Built once a run by ``factory(cell: Cell, options)``."""

    def __init__(self, cell: Cell, options: Any) -> None:
        self.cell = cell
        self.options = options

    @abstractmethod
    def scene(self, plant: Plant, *, seed: int, labels: str) -> Scene:
        """Everything a renderer draws besides the arms, in world coordinates, with ``plant``
        on the cell's soil as :func:`agrisim.robot.cell.place_plant` puts it for the run's
        ``labels`` (``plant`` or ``organs``; everything else is background, label 0).
        ``seed``: the run's ``pcg_seed``, from which a room draws what it randomizes."""


class Rig(ABC):
    """What moves the cameras relative to the plant (``[rig] backend``; ``paper``: the paper's
    UR10s on stands either side of the pot): its arms (URDF, base pose, joints, camera frame,
    home), the obstacles, where the plant stands, and the routine's default viewpoints. Built
    once a run by ``factory(settings: CellConfig, options)``, ``settings`` the run's ``[cell]``."""

    #: the run's bench of plants, set before :meth:`cell` is asked (a rig may size itself to
    #: it; the core then adds a pot for each plant, :func:`agrisim.bench.bench_cell`); empty: one plant
    bench: tuple[BenchPlant, ...] = ()

    def __init__(self, settings: CellConfig, options: Any) -> None:
        self.settings = settings
        self.options = options

    @abstractmethod
    def cell(self) -> Cell:
        """The arms, the static obstacles and the plant centre, world frame (z up)."""

    @abstractmethod
    def setpoints(self, cell: Cell, routine: RoutineConfig) -> dict[str, list[Setpoint]]:
        """Each arm's camera targets in shooting order for ``routine`` (its grid, radius):
        the default viewpoints, which ``routine.csv`` replaces."""


class PlantSpecies(ABC):
    """A plant that can be grown from a seed (``factory(options)``)."""

    def __init__(self, options: Any) -> None:
        self.options = options

    @abstractmethod
    def build(self, seed: int) -> Plant:
        """The plant, in its own frame (origin at the centre of the soil surface, z up), with
        its label table (organ labels where the species has them)."""


class Bridge(ABC):
    """A middleware serving a live session (``agrisim ros``): it turns messages into the
    session's commands and publishes the arms and the views. Built with the opened session
    (:class:`agrisim.plugins.ros.live.LiveSession`) and its options; :meth:`start` connects, :meth:`close`
    disconnects."""

    @abstractmethod
    def start(self) -> None:
        """Connect, advertise and subscribe; raises :class:`agrisim.errors.UserError` naming
        what is missing (no ROS master, the middleware not installed)."""

    @abstractmethod
    def close(self) -> None:
        """Stop publishing and leave the middleware; safe to call twice."""

    def describe(self) -> list[str]:
        """One line per topic or service served, for the command line to print."""
        return []


class Exporter(ABC):
    """Writes a finished run directory in another tool's format: ``agrisim export NAME RUN_DIR
    [OUT]`` (and a sweep's follow-ups, and every rendered run's own ``transforms.json``).

    Built as ``factory(options)`` with the exporter's validated options (its spec's
    ``options_model``; ``--set exporter.NAME.KEY=VALUE`` on the command line), then
    :meth:`export` is called once with:

    * ``run_dir``: the run directory as the user named it: anything, until checked;
    * ``out``: where the export goes: the user's ``OUT``, else ``run_dir /``
      :attr:`default_out`; a file or a folder, as the exporter documents;
    * ``overwrite``: whether an earlier export in ``out`` may be replaced (``--overwrite``);
    * ``progress``: ``progress(done, total)`` for a progress bar, or None.

    It must:

    * read and check everything it needs before writing anything: bad input (not a run
      directory, a run not complete, a missing or unreadable file, an ``OUT`` it cannot honour)
      raises :class:`agrisim.errors.UserError` with a one-line message naming the file or the
      setting, and leaves the disk as it was (the CLI prints it and exits 2);
    * never replace finished work silently: an existing ``out`` without ``overwrite`` is refused
      with :class:`agrisim.errors.OutputError` naming ``--overwrite`` (an exporter whose files
      are a pure function of the run's and that every run writes itself, as nerfstudio's, may
      rewrite them identically);
    * write atomically (:mod:`agrisim.files.atomic`: a file through a temporary file, a folder
      staged beside ``out``), so that an interrupted export leaves the old one or none;
    * never change the run's own files; and return the path it wrote (``out``, usually).
    """

    #: what :meth:`export` counts in ``progress(done, total)`` (the bar's name); None: it
    #: reports no progress
    progress_unit: str | None = None

    def __init__(self, options: Any) -> None:
        self.options = options

    @property
    @abstractmethod
    def default_out(self) -> str:
        """Where the export goes when the user names no ``OUT``: a path relative to the run
        directory (``coco/annotations.json``, ``rosbag``), inside it."""

    @abstractmethod
    def export(
        self,
        run_dir: Path,
        out: Path,
        overwrite: bool = False,
        progress: Callable[[int, int], None] | None = None,
    ) -> Path:
        """Write the export of the run in ``run_dir`` to ``out``; returns the path written."""

    def summary(self, written: Path) -> str:
        """The line the user is told once :meth:`export` wrote ``written``."""
        return f"wrote {written}"
