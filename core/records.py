"""The record of one episode: its state as events and sinks see it (:class:`Run`), each
setpoint's outcome (:class:`SetpointResult`, a row of ``run.json``) and how it ended
(:class:`RunSummary`). Plain dataclasses, so the hook specifications can name them without
importing the episode machinery."""

from __future__ import annotations

import uuid
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from agrisim.config import RunConfig
    from agrisim.interfaces import Reconstruction, SensorGeometry
    from agrisim.robot.cell import Cell
    from agrisim.robot.kinematics import ArmKinematics
    from agrisim.robot.setpoints import Setpoint
    from agrisim.scene.camera import CameraModel
    from agrisim.scene.model import LabelTable, Scene


@dataclass
class SetpointResult:
    """What happened at one setpoint of one arm (a row of ``run.json``)."""

    robot: str
    index: int
    frame: str
    reached: bool
    ee_error_mm: float | None = None  # camera position error after settling
    rot_error_rad: float | None = None
    ik_s: float = 0.0  # wall seconds in IK
    plan_s: float = 0.0  # wall seconds in the planner
    motion_s: float = 0.0  # simulated seconds of the trajectory plus settling
    sim_time: float = 0.0  # simulated time when the setpoint was done
    waited: bool = False  # the other arm moved first because moving together would collide
    contacts: list[str] = field(default_factory=list)
    reason: str = ""


@dataclass
class RunSummary:
    """How the episode ended (``agrisim_run_finished``)."""

    status: str  # complete | failed | interrupted
    setpoints: int
    reached: int
    failed: int
    collisions: int
    sim_time: float
    wall_s: dict[str, float]
    error: str = ""
    metrics: dict[str, Any] | None = None  # headline accuracy per label (metrics.json has all)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class Run:
    """The state of one episode, as sinks see it."""

    config: RunConfig
    cell: Cell
    out_dir: Path
    kinematics: dict[str, ArmKinematics]
    setpoints: dict[str, list[Setpoint]]
    camera: CameraModel
    backends: dict[str, str]
    started_at: str
    backend_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    scene: Scene | None = None  # what the renderer draws (None without a renderer)
    labels: LabelTable | None = None  # the label table of the images
    #: the depth sensor's imager and pose against the camera (None: the exact sensor, or none)
    sensor: SensorGeometry | None = None
    #: the colour camera's imager, its figures and settings (None: noise-free images)
    imager: dict[str, Any] | None = None
    run_id: str = field(default_factory=lambda: uuid.uuid4().hex)
    results: list[SetpointResult] = field(default_factory=list)
    wall_s: dict[str, float] = field(default_factory=dict)
    plant_notes: list[str] = field(default_factory=list)  # how the plant was made (scaled, aged...)
    reconstruction: Reconstruction | None = None  # set when a complete run's views are fused
    metrics: dict[str, Any] | None = None  # metrics.json's content
    #: files a sink writes, by what they are (``{"recording": Path}``), for the user to be told
    outputs: dict[str, Path] = field(default_factory=dict)
    #: what writes the exports a rendered run makes itself (:data:`agrisim.files.exports.RUN_EXPORTS`)
    #: into the run directory it is given, once the run's files are final (the dataset sink calls them)
    exports: list[Callable[[Path], object]] = field(default_factory=list)

    @property
    def seed(self) -> int:
        return self.config.seed
