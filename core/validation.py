"""One validation pass over a run's settings: every backend, option table, capability, name and
file they name, checked against the installed plugins before anything is built or written.

:func:`check_run` is what an episode, a sweep's cells, a compare's episodes, the view-choosing
environment and a live session all call; what it finds (each chosen backend with its validated
options, the camera) is what the episode then builds from. Nothing here grows a plant, reads a
plant file or opens a backend: a plant file is only looked for, a species' options only validated.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pydantic import BaseModel

from agrisim.bench import bench_cell, bench_layout
from agrisim.camera_choice import camera_of
from agrisim.capabilities import check_reconstructor, check_renderer, check_sensor
from agrisim.config import BackendChoice, ImagerConfig, RunConfig, backend_options
from agrisim.errors import ConfigError
from agrisim.interfaces import Imager, Rig
from agrisim.kinds import KINDS, BackendSpec
from agrisim.plant_choice import check_plant_name, draws_points, species_options
from agrisim.registry import Registry, blame, loads_everything, make_plugin_manager, with_own_plugins
from agrisim.robot.cell import Cell
from agrisim.scene.camera import CameraModel

__all__ = ["Chosen", "Validated", "check_run", "imager_spec", "open_imager", "open_rig", "pose_source"]

#: the entry points of agrisim's own rigs, which every run loads whatever plugins are chosen
OWN_RIGS = ("rig-paper", "rig-single-arm", "rig-turntable", "rig-gantry")
#: (the backend, its options validated by its own model)
Chosen = tuple[BackendSpec, BaseModel]


@dataclass
class Validated:
    """What :func:`check_run` found: each chosen backend and its options (None where the run
    has none: no renderer, no reconstruction), the installed sinks' options, the camera."""

    physics: Chosen
    planner: Chosen
    camera: CameraModel
    renderer: Chosen | None = None
    sensor: Chosen | None = None
    recon: Chosen | None = None
    room: Chosen | None = None
    rig: Chosen | None = None
    imager: BackendSpec | None = None
    sinks: dict[str, BaseModel] = field(default_factory=dict)


def check_run(registry: Registry, config: RunConfig, *, preflight: bool = True) -> Validated:
    """Check everything ``config`` names against ``registry``, in the order a run would meet it,
    so that the first bad input is the one reported (a :class:`~agrisim.errors.UserError`).
    ``preflight`` runs the backends' own checks that need this machine (a GPU, a file they would
    write): a run's process does; a sweep or a compare planning runs for other hosts does not."""

    def chosen(kind: str, choice: BackendChoice) -> Chosen:
        spec = registry.get(kind, choice.backend)
        section = KINDS[kind].section
        assert section is not None  # only a kind that a setting chooses has a BackendChoice
        choice.check_tables(section, registry.specs(kind))
        options = backend_options(spec.options_model, choice.options_for(spec.name), f"{kind} backend {spec.name!r}")
        if preflight and spec.preflight is not None:  # e.g. a GPU it needs, a file it reads
            with blame(kind, spec, " checking its settings"):
                spec.preflight(config, options)
        return spec, options

    rig = chosen("rig", config.rig)
    if "backend" not in config.room.model_fields_set and (room := getattr(rig[0].capabilities, "room", None)):
        config.room.backend = room  # (then set, as run.json records it)
    found = Validated(chosen("physics", config.physics), chosen("planner", config.planner), camera_of(config.camera))
    found.rig = rig
    found.sinks = _sink_options(registry, config, preflight)
    if config.recon.poses != "truth":  # a pose source estimates from the finished views
        pose_source(registry, config.recon.poses)
        raise ConfigError(
            f"recon.poses = {config.recon.poses!r} needs the finished run: agrisim colmap RUN, then "
            f"agrisim recon RUN --set recon.poses={config.recon.poses}; a run reconstructs on the true poses"
        )
    found.imager = imager_spec(registry, config.imager)
    _check_species_options(registry, config)
    if config.renderer.backend == "none":
        if config.imager.model != "none":
            raise ConfigError(f"imager {config.imager.model!r} needs a renderer (renderer is 'none')")
        check_plant_name(registry, config)
        # nothing renders, but a typo or a bad value in an option table is still refused
        config.renderer.check_tables("renderer", registry.specs("renderer"))
        config.sensor.check_tables("sensor", registry.specs("sensor"))
        config.recon.check_tables("recon", registry.specs("reconstructor"))
        config.room.check_tables("room", registry.specs("room"))
        return found
    found.renderer = chosen("renderer", config.renderer)
    points = draws_points(registry, config)
    check_renderer(
        found.renderer[0],
        registry.specs("renderer"),
        [config.render.seg_mode],
        config.render.labels,
        points=points,
        lens=not found.camera.pinhole,
        radiance=config.imager.model != "none",
        bench=config.bench is not None,
    )
    found.sensor = chosen("sensor", config.sensor)
    check_sensor(found.sensor[0], registry.specs("sensor"), points=points)
    check_plant_name(registry, config)
    found.room = chosen("room", config.room)
    # Reconstruction fuses rendered views; without a renderer there is nothing to fuse.
    if config.recon.backend != "none":
        check_reconstructor(
            registry.get("reconstructor", config.recon.backend),
            config.render.hide_robots,
            lens=not found.camera.pinhole,
        )
        found.recon = chosen("reconstructor", config.recon)
    else:
        config.recon.check_tables("recon", registry.specs("reconstructor"))
    return found


def _sink_options(registry: Registry, config: RunConfig, preflight: bool) -> dict[str, BaseModel]:
    """Every installed sink's options from ``[sink.NAME]``, validated and pre-flighted: a table
    for a sink that is not installed is refused, as a typo would otherwise be lost (unless
    plugins were selected, ``AGRISIM_LOAD_PLUGINS``: a sink left out ignores its settings,
    ``--no-rrd`` among them)."""
    specs = registry.specs("sink")
    for name in config.sink:
        if name not in specs and loads_everything(registry.pm):
            raise ConfigError(f"[sink.{name}]: no such sink; installed: {', '.join(specs) or 'none'}")
    options = {}
    for name, spec in specs.items():
        options[name] = backend_options(spec.options_model, config.sink.get(name, {}), f"sink {name!r}")
        if preflight and spec.preflight is not None:
            with blame("sink", spec, " checking its settings"):
                spec.preflight(config, options[name])
    return options


def _check_species_options(registry: Registry, config: RunConfig) -> None:
    """Each ``[plants.NAME]`` table of an installed species validates with the species' own
    model (every species also takes ``seed``), whether or not it is the run's plant."""
    species = registry.specs("plant")
    for name, table in config.plants.items():
        if name in species:
            species_options(species[name], name, table, config.seed)


def imager_spec(registry: Registry, settings: ImagerConfig) -> BackendSpec | None:
    """The imager backend ``[imager] model`` names (None for ``none``); an unknown name is
    refused as an invalid setting, listing the installed imagers."""
    if settings.model == "none":
        return None
    specs = registry.specs("imager")
    if settings.model not in specs:
        imagers = ", ".join(["none", *specs])
        raise ConfigError(
            f"invalid setting 'imager.model': unknown imager {settings.model!r}; imagers: {imagers} (got {settings.model!r})"
        )
    return specs[settings.model]


def open_imager(registry: Registry, settings: ImagerConfig, seed: int) -> Imager | None:
    """The imager of a run's ``[imager]`` settings and seed (None for ``none``): what each arm's
    camera shoots through."""
    spec = imager_spec(registry, settings)
    if spec is None:
        return None
    with blame("imager", spec, " opening"):
        imager: Imager = registry.build("imager", spec, settings, seed, spec.options_model())
    return imager


def open_rig(config: RunConfig, registry: Registry | None = None, chosen: Chosen | None = None) -> tuple[Rig, Cell]:
    """The rig ``[rig]`` names (with its options as :func:`check_run` found them, or validated
    here), built from ``[cell]`` through ``registry`` (by default the installed plugins'), and
    its cell: where a run, a finished run's reader or a tool gets its arms and obstacles."""
    if registry is None:  # agrisim's own rigs whatever AGRISIM_LOAD_PLUGINS says, as a run has them
        pm = make_plugin_manager()
        with_own_plugins(pm, names=OWN_RIGS)
        registry = Registry(pm)
    if chosen is None:
        spec = registry.get("rig", config.rig.backend)
        chosen = spec, backend_options(spec.options_model, config.rig.options_for(spec.name), f"rig {spec.name!r}")
    spec, options = chosen
    with blame("rig", spec, " building the cell"):
        rig: Rig = registry.build("rig", spec, config.cell, options)
        rig.bench = tuple(bench_layout(config)) if config.bench is not None else ()
        cell = rig.cell()
    if not cell.arms:  # (a fixed camera is an arm too: a turntable's are one-joint robots)
        raise ConfigError(f"rig {spec.name!r} has no camera: its cell holds no arm to carry one")
    if rig.bench:
        cell = bench_cell(cell, list(rig.bench), spec.name)
    return rig, cell


def pose_source(registry: Registry, name: str) -> BackendSpec:
    """The pose source ``recon.poses`` names; an unknown name is refused, listing them."""
    sources = registry.specs("poses")
    if name not in sources:
        known = ", ".join(["truth", *sources])
        raise ConfigError(
            f"invalid setting 'recon.poses': unknown pose source {name!r}; pose sources: {known} (got {name!r})"
        )
    return sources[name]
