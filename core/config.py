"""Run configuration: validated models, TOML loading and flag overrides.

Configuration is layered: model defaults (which reproduce the paper's experiment) < the TOML
file given with ``--config`` < command-line flags. :func:`merge` is the one pure function that
layers nested dictionaries; :func:`build_config` validates the result. Each backend's own
options live in a table named after it (``[physics.pybullet]``, ``[planner.ompl]``) and are
validated by that backend's options model once the backend is known.
"""

from __future__ import annotations

import copy
import math
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from agrisim.errors import ConfigError
from agrisim.options import Options, refuse_bool_for_number

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


# Defaults are given as Field(default=...), never Field(value, ...): type checkers learn a model's
# constructor from pydantic's dataclass_transform, which counts only the keyword as a default (a
# positional one makes every such field look required).
class _Model(Options):
    # agrisim's own sections are Options too, and also re-validate on assignment.
    model_config = ConfigDict(validate_assignment=True)


class BackendChoice(BaseModel):
    """Which backend of a kind to use, plus per-backend option tables keyed by backend name."""

    model_config = ConfigDict(extra="allow")

    backend: str
    """Name of the backend (see ``agrisim plugins``)."""

    def check_tables(self, section: str, known: Mapping[str, Any]) -> None:
        """Every extra key must name a backend of this kind and its table must validate, even
        for a backend not chosen now (a typo such as ``[physics.pybulet]`` or a bad value for
        the other backend would otherwise be ignored silently). ``known`` maps backend names
        to their specs (``options_model``)."""
        names = sorted(known)
        for key in self.model_extra or {}:
            if key not in names:
                raise ConfigError(
                    f"[{section}] {key!r} is neither a setting nor a {section} backend; "
                    f"settings: {', '.join(type(self).model_fields)}; backends: {', '.join(names)}"
                )
            backend_options(known[key].options_model, self.options_for(key), f"{section} backend {key!r}")

    def options_for(self, name: str) -> dict[str, Any]:
        """The option table for backend ``name`` (empty when not given)."""
        table = (self.model_extra or {}).get(name, {})
        if not isinstance(table, dict):
            raise ConfigError(f"options for backend {name!r} must be a table, got {table!r}")
        return table


class PhysicsChoice(BackendChoice):
    backend: str = "pybullet"
    """Physics backend (``--physics``): pybullet or kinematic, or a plugin's."""


class PlannerChoice(BackendChoice):
    backend: str = "ompl"
    """Motion planner (``--planner``): ompl or direct, or a plugin's."""


class RendererChoice(BackendChoice):
    backend: str = "raycast"
    """Renderer (``--renderer``): raycast or pybullet, or a plugin's."""


class SensorChoice(BackendChoice):
    backend: str = "exact"
    """Depth sensor (``--depth-sensor``): exact (the renderer's depth), azure-kinect-nfov, d435,
    d415, d405, or a plugin's; what it measures goes to ``depth_sensor/`` beside ``depth/``."""


class RigChoice(BackendChoice):
    backend: str = "paper"
    """What moves the cameras (``--rig``): paper (the paper's UR10s, sized by ``[cell]``), or a plugin's."""


class RoomChoice(BackendChoice):
    backend: str = "lab"
    """What surrounds the cell: lab (the paper's laboratory), or a plugin's."""


class ReconChoice(BackendChoice):
    backend: str = "pointcloud"
    """Reconstructor (``--recon``): pointcloud or tsdf, or a plugin's; none: no reconstruction."""
    merged_every: int = Field(default=10, ge=1, le=10_000)
    """Announce the merged clouds (to Rerun) every this many views, and at the end."""
    depth: Literal["sensor", "truth"] = "sensor"
    """The depth the reconstructor is given: ``sensor``, what the run's depth sensor measured
    (``depth_sensor/``; the exact depth with the exact sensor); ``truth``, the exact depth."""
    poses: str = "truth"
    """The camera poses the reconstructor is given: ``truth``, the simulator's; or a pose
    source's (``agrisim recon`` only): ``colmap``, COLMAP's estimates aligned to the world
    (``agrisim colmap RUN`` first), views COLMAP did not register left out: what estimated
    poses cost a reconstruction."""


class MetricsConfig(_Model):
    """How reconstructions are measured against the ground-truth plant."""

    thresholds_mm: list[float] = Field(default=[1.0, 2.0, 5.0], min_length=1, max_length=8)
    """Distances at which precision, recall and F-score are reported, mm."""
    truth_samples: int = Field(default=500_000, ge=1_000, le=20_000_000)
    """Points sampled uniformly on the true plant surface (those on cut-away texels dropped)."""

    @field_validator("thresholds_mm")
    @classmethod
    def _positive(cls, v: list[float]) -> list[float]:
        if any(not (0.0 < t <= 1000.0) for t in v):
            raise ValueError(f"thresholds must lie in (0, 1000] mm, got {v}")
        return sorted(set(v))


class CellConfig(_Model):
    """The robot cell: two arms on stands either side of the plant table."""

    arm_distance: float = Field(default=1.0, gt=0.3, le=3.0)
    """Horizontal distance from the plant centre to each arm's base, m (paper: 1.0)."""
    stand_height: float = Field(default=0.95, ge=0.0, le=3.0)
    """Height of the arms' stands (their bases sit on top), m (paper: 0.95)."""
    stand_size: float = Field(default=0.4, gt=0.0, le=2.0)
    """Side of the square robot stands, m."""
    table_height: float = Field(default=0.80, ge=0.0, le=3.0)
    """Height of the plant table's top, m; the pot stands on it."""
    table_size: float = Field(default=0.5, gt=0.0, le=3.0)
    """Side of the square plant table, m."""
    pot_radius: float = Field(default=0.09, gt=0.0, le=0.5)
    """Pot radius, m."""
    pot_height: float = Field(default=0.14, gt=0.0, le=1.0)
    """Pot height, m."""
    keepout_radius: float = Field(default=0.16, ge=0.0, le=1.0)
    """Radius of a cylinder around the plant that arms must not enter, m (0 disables)."""
    keepout_height: float = Field(default=0.35, ge=0.0, le=2.0)
    """Height of that cylinder above the table, m."""
    arms: int = Field(default=2, ge=1, le=2)
    """Number of arms: 2 as in the paper, or 1 (the arm on the +x side)."""


class RoutineConfig(_Model):
    """Where the camera goes: the paper's hemisphere, or poses from a CSV file."""

    setpoints: str = "5x10"
    """``LxC``: L elevation levels x C azimuth columns per arm (paper: 5x10)."""
    radius: float = Field(default=0.5, gt=0.05, le=1.5)
    """Hemisphere radius around the plant centre, m (paper: 0.5)."""
    phi_deg: tuple[float, float] = (36.0, 540.0 / 7.0)
    """Polar angle range from the zenith, degrees (paper: pi/5 .. 3pi/7)."""
    theta_deg: tuple[float, float] = (180.0 / 19.0, 18.0 * 180.0 / 19.0)
    """Azimuth range of each arm's half, degrees (paper: pi/19 .. 18pi/19)."""
    aim_height: float = Field(default=0.2, ge=-0.5, le=1.0)
    """Cameras look at this point above the hemisphere centre, m: the plant's middle rather
    than the pot's centre, so plants up to 0.4 m stay in view (0: the pot's centre)."""
    csv: Path | None = None
    """CSV of camera poses (columns x, y, z, roll, pitch, yaw; optional robot) instead."""

    @field_validator("setpoints")
    @classmethod
    def _grid(cls, v: str) -> str:
        parse_grid(v)
        return v

    @field_validator("phi_deg", "theta_deg")
    @classmethod
    def _range(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not all(math.isfinite(x) for x in v):
            raise ValueError("angles must be finite")
        return v

    @field_validator("csv")
    @classmethod
    def _csv_exists(cls, v: Path | None) -> Path | None:
        if v is not None and not v.is_file():
            raise ValueError(f"setpoint CSV not found: {v}")
        return v


class MotionConfig(_Model):
    """IK, time-parametrisation and the reach check."""

    velocity_scale: float = Field(default=1.0, gt=0.0, le=1.0)
    """Fraction of the URDF's joint velocity limits used."""
    max_acceleration: float = Field(default=4.0, gt=0.0, le=100.0)
    """Joint acceleration limit, rad/s^2."""
    max_jerk: float = Field(default=40.0, gt=0.0, le=10000.0)
    """Joint jerk limit, rad/s^3."""
    reach_tolerance_mm: float = Field(default=0.05, gt=0.0, le=100.0)
    """A setpoint is reached when the camera is this close to it, mm (paper: 0.05)."""
    reach_tolerance_rad: float = Field(default=1e-4, gt=0.0, le=1.0)
    """... and its orientation this close, rad."""
    reach_timeout: float = Field(default=5.0, gt=0.0, le=600.0)
    """Simulated seconds to settle after the trajectory ends before giving up (paper: 5)."""
    ik_restarts: int = Field(default=16, ge=0, le=1000)
    """Random restarts of IK besides the warm start from the current joints."""
    ik_max_restarts: int = Field(default=100, ge=0, le=100000)
    """Random restarts allowed while no collision-free solution has been found."""
    ik_candidates: int = Field(default=3, ge=1, le=100)
    """IK solutions (nearest first) the planner tries before a setpoint is given up."""
    ik_max_iterations: int = Field(default=200, ge=1, le=100000)
    """Iterations per IK attempt."""
    collision_check_step: float = Field(default=0.02, gt=0.0, le=1.0)
    """Joint-space resolution of edge and trajectory collision checks, rad."""


class OutputConfig(_Model):
    """Where results go."""

    out: Path | None = None
    """Output directory (default: runs/<timestamp>)."""
    overwrite: bool = False
    """Replace an existing output directory."""
    resume: bool = False
    """Continue an interrupted run in the output directory with its saved configuration."""

    @model_validator(mode="after")
    def _exclusive(self) -> OutputConfig:
        if self.overwrite and self.resume:
            raise ValueError("--overwrite and --resume exclude each other")
        return self


class CameraConfig(_Model):
    """The camera on each arm's flange."""

    preset: str = "rpi3-wide-1080p"
    """Camera preset (the paper's Raspberry Pi v3 Wide, a pinhole: 6.45 x 3.63 mm sensor,
    2.75 mm; ``rpi-camera-3-wide`` with its barrel lens; ``agrisim.scene.camera.PRESETS``)."""
    resolution: str | None = None
    """``WxH`` overriding the preset's 1920x1080 (the field of view stays)."""
    calibration: Path | None = None
    """A calibration file (OpenCV's YAML/JSON, or ROS's camera_info YAML) giving the camera
    instead of the preset: its size, ``K`` and lens."""

    @model_validator(mode="after")
    def _one_camera(self) -> CameraConfig:
        if self.calibration is not None and self.resolution is not None:
            raise ValueError("camera.calibration fixes the image size; leave camera.resolution unset")
        return self

    @field_validator("resolution")
    @classmethod
    def _resolution(cls, v: str | None) -> str | None:
        if v is not None:
            from agrisim.scene.camera import parse_resolution

            parse_resolution(v)
        return v


class ImagerConfig(_Model):
    """The colour camera's sensor and image processing (an imager backend,
    :class:`agrisim.interfaces.Imager`): ``none`` keeps the renderer's noise-free images."""

    model: str = "none"
    """``none``, ``imx708`` (Camera Module 3) or ``ov2740`` (RealSense D4xx colour), or a
    plugin's; ``--imager``."""
    lux: float = Field(default=1000.0, gt=0.0, le=1e6)
    """Illuminance, lux, that the renderer's irradiance 1 stands for (a lab under ceiling lights:
    1000 lx; sunlight: 100,000)."""
    exposure: Literal["auto"] | float = "auto"
    """``auto`` (the sensor's auto-exposure, converging from view to view) or a fixed exposure
    time, seconds (``--exposure``)."""
    gain: float = Field(default=1.0, ge=1.0, le=64.0)
    """Analogue gain with a fixed exposure."""
    ae_frames: int = Field(default=15, ge=0, le=10_000)
    """Frames the camera streams (and the auto-exposure meters) between two shots: 15 is half a
    second at 30 fps, the arm's settling."""
    jpeg_quality: int = Field(default=0, ge=0, le=100)
    """0: the developed image stored losslessly; 1..100: through JPEG at that quality, as a
    streaming camera sends it (``--jpeg-quality``)."""
    bit_depth: int | None = Field(default=None, ge=8, le=16)
    """The ADC's bits, overriding the sensor's (its black level scaled with it); None: the
    sensor's own (10 for both presets)."""
    raw: bool = False
    """Also write each view's raw Bayer frame (``raw/<frame>.png``, uint16 digital numbers)."""

    @field_validator("exposure")
    @classmethod
    def _exposure(cls, v: str | float) -> str | float:
        if v != "auto" and not 1e-6 <= float(v) <= 10.0:
            raise ValueError(f"exposure {v} s is outside 1e-06..10 s (or auto)")
        return v


class RenderConfig(_Model):
    """Run-wide rendering settings, whichever renderer draws."""

    seg_mode: Literal["texture", "repopa"] = "texture"
    """``texture``: the paper's label texture with opacity thresholded; ``repopa``: opacity
    ignored for the label pass (EasySynth's way), RGB and depth still cut out."""
    labels: Literal["plant", "organs"] = "plant"
    """One label for the whole plant, or one per organ where the species has them."""
    hide_robots: bool = False
    """Render without the arms (the paper's NeRF captures)."""
    depth_format: Literal["png16", "exr", "both"] = "png16"
    """How the dataset stores depth: ``png16`` (uint16 whole millimetres, 0 = no hit), ``exr``
    (float32 planar z in metres, exact, 0 = no hit) or both; reconstruction uses the exact
    depth when it is there."""


class PlantFileConfig(_Model):
    """How a plant given as a file (``--plant PATH``) is read."""

    label_texture: Path | None = None
    """PNG of label ids or label colours at the albedo's UVs."""
    material_labels: dict[str, str] | None = None
    """Material-name pattern -> organ name (``{"Leaf*" = "leaf", "Bark" = "stem"}``)."""
    alpha_cutoff: float | None = Field(default=None, ge=0.0, le=1.0)
    """Cutoff for every MASK/BLEND material instead of the file's."""
    up: Literal["y", "z"] | None = None
    """The asset's up axis (glTF and OBJ default to y)."""
    scale: float = Field(default=1.0, gt=0.0, le=1000.0)
    """Multiplies the coordinates (0.01 for an asset in centimetres)."""
    root: Path | None = None
    """Directory the asset and the files it names must lie in (no escaping it)."""
    label_names: dict[str, str] | None = None
    """Names of label ids (``{"1" = "leaf", "2" = "stem"}``): of a point cloud's ``label``
    property, or of a label texture's ids (``label_texture``)."""


class PointsConfig(_Model):
    """Drawing the plant as points (the paper's Table 3): a point-cloud file always is."""

    count: int | None = None
    """``--as-points N``: draw the plant (a species, a crop, a mesh file) as N points sampled
    on its opaque surface; None: as it is."""
    size: float | None = None
    """``--point-size S``: diameter of every point's sphere, m; None: twice the cloud's median
    spacing."""


class BenchPlantConfig(_Model):
    """One plant of a listed bench (``[[bench.plants]]``)."""

    x: float = Field(ge=-5.0, le=5.0)
    """Where its pot stands from the cell's plant centre, x then y, m."""
    y: float = Field(ge=-5.0, le=5.0)
    plant: str | None = None
    """A species or a plant file, as ``--plant``; None: the run's plant."""
    seed: int | None = Field(default=None, ge=0, le=2**32 - 1)
    """The individual it grows; None: the run's plant seed plus its index on the bench."""


class BenchConfig(_Model):
    """Several plants in pots on one table: a grid (``--bench RxC --spacing M``) or a list."""

    grid: str | None = None
    """``RxC``: R rows along y by C columns along x, centred on the cell's plant centre."""
    spacing: float = Field(default=0.5, gt=0.0, le=3.0)
    """Distance between neighbouring pots of the grid, centre to centre, m."""
    plants: list[BenchPlantConfig] = []
    """The plants one by one, instead of a grid."""

    @model_validator(mode="after")
    def _one_layout(self) -> BenchConfig:
        if (self.grid is None) == (not self.plants):
            raise ValueError("[bench] takes a grid (--bench RxC) or a list of [[bench.plants]], one of them")
        if self.grid is not None and math.prod(parse_grid(self.grid, "bench")) > 99:
            raise ValueError(f"bench {self.grid}: at most 99 plants")
        return self


class RunConfig(_Model):
    """Everything one episode needs. Defaults reproduce the paper's experiment."""

    seed: int = Field(default=0, ge=0, le=2**32 - 1)
    """Seed for IK restarts and sampling planners."""
    plant: str = "indian_cress"
    """Plant species (``agrisim plants``) or a glTF/GLB/OBJ file (``--plant``)."""
    plant_file: PlantFileConfig = PlantFileConfig()
    """Options for a plant read from a file."""
    points: PointsConfig = PointsConfig()
    """The plant as points (``--as-points``, ``--point-size``)."""
    bench: BenchConfig | None = None
    """Several plants instead of one (``--bench``); None: one plant in one pot."""
    plants: dict[str, dict[str, Any]] = {}
    """Options per plant species (``[plants.boxwood]``), validated by the species' own model;
    every species also takes ``seed`` (``--plant-seed``): the individual it grows, 0 to 2^32 - 1,
    by default the run's ``seed``."""
    pcg_seed: int = Field(default=42, ge=0, le=2**32 - 1)
    """Seed of what the room randomizes (the lab's clutter: the paper's PCG Seed, 42)."""
    physics: PhysicsChoice = PhysicsChoice()
    """Physics backend and per-backend options (``[physics.pybullet]``)."""
    planner: PlannerChoice = PlannerChoice()
    """Motion planner and per-backend options (``[planner.ompl]``)."""
    renderer: RendererChoice = RendererChoice()
    """Renderer and per-backend options (``[renderer.raycast]``)."""
    render: RenderConfig = RenderConfig()
    imager: ImagerConfig = ImagerConfig()
    """The colour camera's sensor and processing (``--imager``); ``none``: noise-free images."""
    sensor: SensorChoice = SensorChoice()
    """Depth sensor and per-backend options (``[sensor.azure-kinect-nfov]``)."""
    recon: ReconChoice = ReconChoice()
    """Reconstructor and per-backend options (``[recon.pointcloud]``, ``[recon.tsdf]``)."""
    metrics: MetricsConfig = MetricsConfig()
    rig: RigChoice = RigChoice()
    """What moves the cameras and per-rig options (``[rig.paper]``), built from ``cell``."""
    cell: CellConfig = CellConfig()
    room: RoomChoice = RoomChoice()
    """What surrounds the cell and per-room options (``[room.lab]``)."""
    routine: RoutineConfig = RoutineConfig()
    camera: CameraConfig = CameraConfig()
    motion: MotionConfig = MotionConfig()
    output: OutputConfig = OutputConfig()
    sink: dict[str, dict[str, Any]] = {}
    """Options per sink (``[sink.rerun]``), validated by the sink's own model. Every installed
    sink observes every run."""


def depth_read(config: RunConfig) -> str:
    """Which depth a reconstruction of ``config`` reads, as metrics.json says it: ``truth``
    (``recon.depth = "truth"``), or ``sensor:NAME`` (``sensor:exact``: the exact depth too)."""
    return "truth" if config.recon.depth == "truth" else f"sensor:{config.sensor.backend}"


def parse_grid(text: str, what: str = "setpoints") -> tuple[int, int]:
    """``"5x10"`` -> (5, 10); ``what`` names the setting in messages (``bench``: rows x columns)."""
    form = "LxC (e.g. 5x10)" if what == "setpoints" else "RxC (e.g. 2x3)"
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise ValueError(f"{what} must look like {form}, got {text!r}")
    levels, columns = int(parts[0]), int(parts[1])
    if not (1 <= levels <= 100 and 1 <= columns <= 100):
        raise ValueError(f"{what} {text!r}: {form[0]} and C must be between 1 and 100")
    return levels, columns


def merge(base: Mapping[str, Any], override: Mapping[str, Any]) -> dict[str, Any]:
    """Nested dictionaries layered: ``override`` wins, tables merge key by key."""
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


def first_difference(a: Any, b: Any, prefix: str = "") -> tuple[str, Any, Any] | None:
    """The first dotted key where two JSON-like trees differ, with both values, or None."""
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        for key in sorted(set(a) | set(b)):
            d = first_difference(a.get(key), b.get(key), f"{prefix}{key}.")
            if d is not None:
                return d
        return None
    return None if a == b else (prefix.rstrip(".") or "config", a, b)


def outcome_settings(config: RunConfig) -> dict[str, Any]:
    """The settings that decide a run's results (JSON): all but where they go (``output``)
    and who watches (``sink``). A resumed run must agree with its saved run on these."""
    return {k: v for k, v in config.model_dump(mode="json").items() if k not in ("output", "sink")}


def load_toml(path: Path) -> dict[str, Any]:
    """Read a TOML configuration file; unreadable or malformed files are a ConfigError."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read config file {path}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"malformed TOML in {path}: {exc}") from None


def _describe(exc: ValidationError) -> str:
    err = exc.errors()[0]
    where = ".".join(str(p) for p in err["loc"])
    msg = err["msg"].removeprefix("Value error, ")
    if not where:  # a check across settings names them itself
        return msg
    if err["type"] == "extra_forbidden":
        return f"unknown setting {where!r}"
    return f"invalid setting {where!r}: {msg} (got {err.get('input')!r})"


#: Settings that moved into one backend's own options, still accepted where they used to be:
#: the familiar flags set them there (``--plant-age``, ``--plant-seed``, ``--shadow-samples``, ``--supersample``,
#: ``--rrd``, ``--no-rrd``, ``--spawn``), and so may older TOML files and saved runs.
#: old dotted key -> (the table it now lives in, its name there, how its value maps). In the
#: table path, ``{plant}`` and ``{renderer}`` stand for the chosen plant and renderer.
ALIASES: dict[str, tuple[tuple[str, ...], str, Callable[[Any], Any]]] = {
    "plant_age": (("plants", "{plant}"), "age", lambda v: v),
    "plant_seed": (("plants", "{plant}"), "seed", lambda v: v),
    "render.shadow_samples": (("renderer", "{renderer}"), "shadow_samples", lambda v: v),
    "render.supersample": (("renderer", "{renderer}"), "supersample", lambda v: v),
    "output.rrd": (("sink", "rerun"), "path", lambda v: v),
    "output.no_rrd": (("sink", "rerun"), "save", lambda v: not v if isinstance(v, bool) else v),
    "output.spawn": (("sink", "rerun"), "spawn", lambda v: v),
}


def resolve_aliases(data: Mapping[str, Any]) -> dict[str, Any]:
    """``data`` with every :data:`ALIASES` key moved to where it lives now. An alias wins over
    the table it names (a flag is the most specific layer). With no renderer (``none``) the
    renderer's aliases have nothing to set and are dropped."""
    out = copy.deepcopy(dict(data))
    names = {
        "plant": out.get("plant", RunConfig.model_fields["plant"].default),
        "renderer": (out.get("renderer") or {}).get("backend", RendererChoice().backend)
        if isinstance(out.get("renderer"), Mapping)
        else RendererChoice().backend,
    }
    for old, (path, key, convert) in ALIASES.items():
        *parents, leaf = old.split(".")
        node: Any = out
        for p in parents:
            node = node.get(p) if isinstance(node, Mapping) else None
        if not isinstance(node, dict) or leaf not in node:
            continue
        value = convert(node.pop(leaf))
        table = [part.format(**names) for part in path]
        if table[:2] == ["renderer", "none"]:
            continue
        target = out
        for part in table:
            nxt = target.get(part)
            if not isinstance(nxt, dict):
                nxt = {} if nxt is None else nxt
                target[part] = nxt
            if not isinstance(nxt, dict):
                raise ConfigError(f"{old}: [{'.'.join(table)}] must be a table, got {nxt!r}")
            target = nxt
        target[key] = value
    return out


def build_config(*layers: Mapping[str, Any]) -> RunConfig:
    """Validate the layered dictionaries into a :class:`RunConfig` (:data:`ALIASES` resolved)."""
    data: dict[str, Any] = {}
    for layer in layers:
        data = merge(data, layer)
    data = resolve_aliases(data)
    try:
        return RunConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_describe(exc)) from None


def backend_options(model: type[BaseModel], table: Mapping[str, Any], what: str) -> BaseModel:
    """Validate one backend's option table with its own model (a plugin's models do not derive
    from agrisim's, so the checks every setting gets are applied here too)."""
    try:
        for key, value in table.items():
            refuse_bool_for_number(model, key, value)
    except ValueError as exc:
        raise ConfigError(f"{what}: invalid setting {key!r}: {exc}") from None
    try:
        return model.model_validate(dict(table))
    except ValidationError as exc:
        raise ConfigError(f"{what}: {_describe(exc)}") from None
