"""Every hook agrisim calls, in one place.

Two families:

* **Providers** (``agrisim_physics``, ``agrisim_renderers``, ``agrisim_sensors``, ``agrisim_imagers``, ``agrisim_planners``,
  ``agrisim_reconstructors``, ``agrisim_pose_sources``, ``agrisim_plants``, ``agrisim_plant_formats``, ``agrisim_rooms``, ``agrisim_rigs``, ``agrisim_sinks``, ``agrisim_bridges``,
  ``agrisim_exporters``) return a list of
  :class:`agrisim.BackendSpec`. Results of all plugins are concatenated; a name provided twice is
  an error naming both distributions. They are called once per run, never in the inner loop.
  ``agrisim_commands`` returns :class:`agrisim.commands.Command` s, the subcommands of the
  ``agrisim`` command line (agrisim's own among them).
* **Events** (``agrisim_run_started`` ... ``agrisim_run_finished``) announce what an episode does.
  Sinks (the Rerun recording, the dataset files) are plugins on these hooks. Return values are
  ignored.

Signatures may gain keyword arguments in later versions; implementations take only the
arguments they need, as pluggy allows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from agrisim.commands import Command
    from agrisim.interfaces import Capture, Trajectory
    from agrisim.kinds import BackendSpec
    from agrisim.records import Run, RunSummary

PROJECT = "agrisim"
hookspec = pluggy.HookspecMarker(PROJECT)


# ---------------------------------------------------------------- the command line


@hookspec
def agrisim_commands() -> list[Command]:
    """Subcommands of ``agrisim``: each a name, a line of help, its flags and its function
    (:class:`agrisim.commands.Command`). agrisim's own come first, in their order, then the
    others' by name; a name added twice is an error naming both plugins."""


# ---------------------------------------------------------------- backend providers


@hookspec
def agrisim_physics() -> list[BackendSpec]:
    """Physics backends. The core calls ``factory(cell: Cell, options) -> PhysicsBackend``:
    the robot cell (arms, obstacles) and the backend's validated options; the result must be an
    :class:`agrisim.interfaces.PhysicsBackend`."""


@hookspec
def agrisim_renderers() -> list[BackendSpec]:
    """Renderers. The core calls ``factory(scene: Scene, cell: Cell, settings: RenderConfig,
    options) -> Renderer``: what to draw, the arms' URDFs, the run-wide rendering settings and
    the backend's options; the result must be an :class:`agrisim.interfaces.Renderer`. Declare
    :class:`agrisim.capabilities.RendererCapabilities` in the spec."""


@hookspec
def agrisim_sensors() -> list[BackendSpec]:
    """Depth sensors. The core calls ``factory(scene: Scene, cell: Cell, settings:
    RenderConfig, options) -> DepthSensor`` when the run renders, with what the renderer gets;
    the result must be an :class:`agrisim.interfaces.DepthSensor`, whose measurement the run
    writes as ``depth_sensor/`` and reconstructs from (``recon.depth = "sensor"``)."""


@hookspec
def agrisim_imagers() -> list[BackendSpec]:
    """Imagers: a colour camera's sensor and image processing, chosen by ``[imager] model``
    (``--imager``; ``none``: no imager, the renderer's noise-free images). The core calls
    ``factory(settings: ImagerConfig, seed: int, options) -> Imager`` once per arm's camera with
    the run's ``[imager]`` settings and seed; the result must be an
    :class:`agrisim.interfaces.Imager`, whose shots replace the renderer's RGB."""


@hookspec
def agrisim_planners() -> list[BackendSpec]:
    """Motion planners. The core calls ``factory(options) -> Planner``; the result must be an
    :class:`agrisim.interfaces.Planner`."""


@hookspec
def agrisim_reconstructors() -> list[BackendSpec]:
    """Reconstructors. The core calls ``factory(labels: LabelTable, options) -> Reconstructor``:
    the run's label table and the backend's options; the result must be an
    :class:`agrisim.interfaces.Reconstructor`."""


@hookspec
def agrisim_plants() -> list[BackendSpec]:
    """Plant species. The core calls ``factory(options) -> PlantSpecies`` and then
    ``.build(seed)``; the result must be an :class:`agrisim.interfaces.PlantSpecies`."""


@hookspec(firstresult=True)
def agrisim_plant_unavailable(name: str) -> str | None:
    """Why the plant ``name``, which no provider lists, is one this plugin would provide but
    cannot here (e.g. its optional dependency is not installed): a one-line message naming what
    to install, or None. Asked only before agrisim reports an unknown plant."""


@hookspec
def agrisim_pose_sources() -> list[BackendSpec]:
    """Pose sources: camera poses estimated from a finished run's views, chosen by
    ``recon.poses`` (``colmap``; ``truth`` is the simulator's own). The core calls
    ``factory(options) -> PoseSource`` when ``agrisim recon`` reads a run; the result must be an
    :class:`agrisim.interfaces.PoseSource`, whose poses the views are fused at."""


@hookspec
def agrisim_plant_formats() -> list[BackendSpec]:
    """Plant file formats: readers of the plant files ``--plant FILE`` names (glTF, OBJ, PLY,
    PCD are agrisim's). The core calls ``factory(options) -> PlantReader`` and asks each reader
    in turn, third parties' first, whether it claims the path; the first that does reads it. The
    result must be an :class:`agrisim.interfaces.PlantReader`."""


@hookspec
def agrisim_rooms() -> list[BackendSpec]:
    """Rooms: what surrounds the cell, chosen by ``[room] backend`` (``lab``: the paper's
    laboratory). The core calls ``factory(cell: Cell, options) -> Room`` when the run renders;
    the result must be an :class:`agrisim.interfaces.Room`, whose scene the renderers draw."""


@hookspec
def agrisim_rigs() -> list[BackendSpec]:
    """Rigs: what moves the cameras relative to the plant, chosen by ``[rig] backend`` (``paper``:
    the paper's two UR10s). The core calls ``factory(settings: CellConfig, options) -> Rig``; the
    result must be an :class:`agrisim.interfaces.Rig`, whose cell and viewpoints a run uses."""


@hookspec
def agrisim_sinks() -> list[BackendSpec]:
    """Sinks: observers of every run. The core calls ``factory(run: Run, options)`` with the
    :class:`agrisim.records.Run` and the sink's options from ``[sink.NAME]`` (validated by its
    ``options_model``); it returns an object whose event hook implementations are registered
    for that run only (or ``None`` to stay out of it, e.g. the Rerun sink under ``--no-rrd``).
    Per-run objects keep sinks' state out of module globals. A spec's ``preflight(config,
    options)`` runs while the run is validated, before anything is written (the Rerun sink
    refuses to replace a recording without ``--overwrite`` there)."""


@hookspec
def agrisim_bridges() -> list[BackendSpec]:
    """Middleware bridges for live sessions (``agrisim ros --ros 1|2`` picks ``ros1`` or
    ``ros2``). The core calls ``factory(session: LiveSession, options) -> Bridge`` with the
    opened :class:`agrisim.plugins.ros.live.LiveSession` and the bridge's validated options; the bridge
    registers its own event hook implementations (``agrisim_capture``, to publish views) on
    ``session.pm``."""


@hookspec
def agrisim_exporters() -> list[BackendSpec]:
    """Exporters of a finished run directory to another tool's format (``agrisim export NAME
    RUN_DIR [OUT]``: the spec's name is the command's NAME). The core calls ``factory(options)
    -> Exporter`` with the exporter's validated options (``--set exporter.NAME.KEY=VALUE``) and
    then ``export(run_dir, out, overwrite, progress)``; the result must be an
    :class:`agrisim.interfaces.Exporter`, whose docstring is the contract (check everything
    first; bad input is a one-line :class:`agrisim.errors.UserError` with nothing written; no
    earlier export replaced without ``overwrite``). Importing the provider's module should stay
    light: give the format's library to the factory (``lazy("pkg.module:MyExporter")``) or import
    it inside :meth:`~agrisim.interfaces.Exporter.export`."""


# ---------------------------------------------------------------- episode events


@hookspec
def agrisim_run_started(run: Run) -> None:
    """The run is validated and its backends are built; nothing has moved yet.

    ``run.config`` is the configuration actually used, ``run.cell`` the robot cell, and
    ``run.out_dir`` the output directory (already created)."""


@hookspec
def agrisim_trajectory(run: Run, robot: str, trajectory: Trajectory) -> None:
    """``robot`` moved towards ``trajectory.setpoint``: planned and executed joint paths,
    sampled in simulated time (``trajectory.t``, seconds since the run started)."""


@hookspec
def agrisim_setpoint(run: Run, robot: str, result: Any) -> None:
    """A setpoint has been handled (reached or not): ``result`` is a
    :class:`agrisim.records.SetpointResult` with the reason when it failed."""


@hookspec
def agrisim_capture(run: Run, capture: Capture) -> None:
    """A camera captured a frame at a reached setpoint. Without a renderer the capture holds
    only the camera pose and intrinsics."""


@hookspec
def agrisim_cloud(run: Run, label: str, cloud: Any, merged: bool) -> None:
    """A point cloud for ``label`` (a label name, or ``"all"``): one view's contribution
    (``merged=False``) or the merge so far (``merged=True``: every ``recon.merged_every``
    views and at the end). ``cloud`` is an :class:`agrisim.interfaces.Cloud` (world points in
    metres, N x 3, and uint8 colours). A surface reconstructor announces its mesh's vertices."""


@hookspec
def agrisim_run_finished(run: Run, summary: RunSummary) -> None:
    """The episode ended (``summary.status`` says how). Sinks flush and close here."""
