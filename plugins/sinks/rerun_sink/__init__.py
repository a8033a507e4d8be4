"""The ``rerun`` sink: the episode as a Rerun recording (``OUT/recording.rrd``).

One :class:`rerun.RecordingStream` per run (never the process-global one), written to
``OUT/recording.rrd`` (or ``[sink.rerun] path``, ``--rrd``) and, with ``spawn`` (``--spawn``),
streamed to a spawned viewer as well, with ``connect`` (``--serve-web``) to a Rerun server;
``save = false`` (``--no-rrd``) writes no file. Two timelines: ``setpoint`` (sequence, the setpoint index) and ``sim_time`` (duration,
simulated seconds since the run started). Every temporal row carries both, so scrubbing either
shows the same state.

Entity layout (``world/`` is z up; every path is built by :class:`entities.paths`, which other
plugins logging into the same recording should reuse)::

    world                               ViewCoordinates RIGHT_HAND_Z_UP (static)
    world/cell/<obstacle>               Boxes3D / Cylinders3D (static)
    world/<robot>/<link>                Transform3D world_T_link over time
    world/<robot>/<link>/visual_<i>     Asset3D (GLB) or Boxes3D, static, link_T_visual
    world/<robot>/camera                Transform3D world_T_camera + Pinhole (OpenCV RDF)
    world/<robot>/camera/{rgb,labels,depth}   Image (JPEG), SegmentationImage, DepthImage (uint16 mm;
                                        a depth sensor's measurement where the run has one)
    world/<robot>/camera/depth_truth    DepthImage of the exact depth, beside a depth sensor's
    world/<robot>/camera/instances      SegmentationImage of leaf instance ids (when the plant has them)
    world/<robot>/planned|executed      LineStrips3D of the camera position per move
    world/setpoints/<robot>             Points3D (colour = pending/reached/failed)
    world/setpoints/<robot>/view        Arrows3D, the camera's viewing direction
    world/clouds/view|merged/<label>    Points3D per view and merged, per label
    metrics/<robot>/ee_error_mm         Scalars
    log/<robot>                         TextLog per setpoint
    run/config, run/summary             TextDocument

Arm motion is logged decimated to :data:`TRANSFORM_RATE` Hz of simulated time (every link at
every physics step would dominate the file), always including each move's last sample.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from agrisim import BackendSpec, hookimpl
from agrisim.errors import OutputError

from .options import RerunOptions

if TYPE_CHECKING:
    from agrisim.config import RunConfig
    from agrisim.records import Run

    from .recording import RerunSink


def preflight(config: RunConfig, options: RerunOptions) -> None:
    """A recording file outside the run directory is finished work too: replaced only under
    ``--overwrite``."""
    if options.save and options.path is not None and options.path.expanduser().exists() and not config.output.overwrite:
        raise OutputError(f"--rrd {options.path} already exists; pass --overwrite to replace it")


def make_sink(run: Run, options: RerunOptions) -> RerunSink | None:
    """The sink for ``run``, or None when it neither saves nor spawns (Rerun is then never
    imported)."""
    if not options.save and not options.spawn and options.connect is None:
        return None
    from .recording import RerunSink

    if options.save:
        run.outputs["recording"] = options.recording_path(run.out_dir)
    return RerunSink(run, options)


@hookimpl
def agrisim_sinks() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="rerun",
            factory=make_sink,
            description="Rerun recording (OUT/recording.rrd or --rrd; --spawn streams to a viewer)",
            options_model=RerunOptions,
            preflight=preflight,
        )
    ]


def __getattr__(name: str) -> Any:
    # The sink class and its helpers stay importable from here without the provider importing
    # them (``agrisim plugins`` loads this module).
    if name == "RerunSink":
        from .recording import RerunSink

        return RerunSink
    raise AttributeError(name)


__all__ = ["RerunOptions", "RerunSink", "make_sink", "preflight"]
