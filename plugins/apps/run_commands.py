"""The commands that make or use one run: ``run``, ``ros``, ``recon``, ``render``, ``export``,
``colmap`` and ``view``. Each is a :class:`~agrisim.commands.Command`, its flags and the
function of its parsed flags, registered by :mod:`agrisim.plugins.apps.commands`."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agrisim.app.arguments import fail
from agrisim.commands import Command
from agrisim.config import RunConfig, build_config, first_difference, load_toml, outcome_settings
from agrisim.errors import UserError
from agrisim.files import layout
from agrisim.interfaces import ALL
from agrisim.plugins.apps.flags import (
    apply_sets,
    episode_flags,
    overrides_from_args,
    parse_value,
    set_dotted,
    set_flag,
)
from agrisim.plugins.apps.web import web_address, web_flags


def _run_arguments(run: argparse.ArgumentParser) -> None:
    episode_flags(run)
    run.add_argument(
        "--serve-web",
        action="store_true",
        help="stream the run live to Rerun's web viewer, served here (print its address; after the run, serve until Ctrl-C)",
    )
    web_flags(run)
    run.add_argument(
        "--resume",
        action="store_true",
        default=None,
        help="continue the unfinished run in --out with its saved configuration",
    )
    set_flag(run, "any setting by its dotted name, e.g. physics.pybullet.position_gain=0.5")


def _ros_arguments(ros: argparse.ArgumentParser) -> None:
    ros.add_argument("--ros", choices=["1", "2"], required=True, help="ROS 1 (Debian's rospy) or ROS 2 (Cyclone DDS)")
    ros.add_argument(
        "--routine", action="store_true", help="run the paper's setpoints while serving, then go on serving"
    )
    ros.add_argument("--rate", type=float, metavar="HZ", help="/joint_states and /tf rate (default: 50)")
    ros.add_argument(
        "--real-time-factor",
        type=float,
        default=1.0,
        metavar="F",
        help="simulated seconds per wall second when replaying motion (default: 1; 0: as fast as it computes)",
    )
    episode_flags(ros)
    ros.set_defaults(resume=None)
    set_flag(ros, "any setting by its dotted name, e.g. physics.pybullet.position_gain=0.5")


def _recon_arguments(recon: argparse.ArgumentParser) -> None:
    recon.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a complete run's output directory")
    recon.add_argument("--recon", metavar="NAME", help="reconstructor (default: the run's own)")
    recon.add_argument("--out", type=Path, metavar="DIR", help="write clouds/ and metrics.json here (default: RUN_DIR)")
    recon.add_argument("--overwrite", action="store_true", help="replace existing clouds and metrics.json")
    set_flag(recon, "recon.* or metrics.* settings, e.g. recon.tsdf.voxel_size=0.003")


def _render_arguments(render: argparse.ArgumentParser) -> None:
    render.add_argument("run_dirs", type=Path, nargs="+", metavar="RUN_DIR", help="complete runs' output directories")
    render.add_argument("--renderer", default="mitsuba", metavar="NAME", help="a renderer that can re-render (mitsuba)")
    render.add_argument(
        "--out", type=Path, metavar="DIR", help="output directory of one run (default: RUN_DIR-<renderer>)"
    )
    render.add_argument(
        "--ray-address",
        metavar="ADDR",
        help="join this Ray cluster (default: a local one where there are several runs or GPUs)",
    )
    render.add_argument(
        "--gpus",
        type=int,
        metavar="N",
        help="GPUs to draw on: a run each, or one run's frames shared among them (default: every GPU)",
    )
    render.add_argument(
        "--gpu-resource",
        default="GPU",
        metavar="NAME",
        help="the Ray resource a GPU task takes one of (default: GPU; a custom resource a cluster declares)",
    )
    render.add_argument("--overwrite", action="store_true", help="replace an existing --out (or RUN_DIR's own RGB)")
    set_flag(render, "renderer.* settings, e.g. renderer.mitsuba.spp=64")


def _export_arguments(export: argparse.ArgumentParser) -> None:
    export.add_argument(
        "format",
        metavar="NAME",
        help="the exporter: nerfstudio (transforms.json), coco, rosbag, or one a plugin adds",
    )
    export.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run's output directory (agrisim run --out)")
    export.add_argument(
        "out", type=Path, nargs="?", default=None, metavar="OUT", help="where the export goes (default: in RUN_DIR)"
    )
    export.add_argument("--overwrite", action="store_true", help="replace an existing export (coco, rosbag)")
    set_flag(export, "an option of the exporter by its dotted name, exporter.NAME.KEY=VALUE")


def _colmap_arguments(colmap: argparse.ArgumentParser) -> None:
    colmap.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a complete run's output directory")
    colmap.add_argument(
        "--priors",
        default="robot",
        metavar="robot|none",
        help="robot: the arms' kinematics give COLMAP each view's centre as a pose prior and check each matched "
        "pair's rotation (default); none: COLMAP from the images alone, as the paper ran it",
    )
    colmap.add_argument(
        "--prior-std-mm",
        type=float,
        default=10.0,
        metavar="MM",
        help="how far the priors are trusted, one standard deviation (10)",
    )
    colmap.add_argument(
        "--matcher",
        default="exhaustive",
        metavar="exhaustive|sequential|spatial",
        help="match every pair of views (default), each with the next --overlap views of the routine, or each with "
        "its --overlap nearest by prior position (needs --priors robot)",
    )
    colmap.add_argument(
        "--overlap",
        type=int,
        default=10,
        metavar="N",
        help="sequential and spatial matching: views matched with each (10)",
    )
    colmap.add_argument(
        "--intrinsics",
        default="known",
        metavar="known|estimated",
        help="the run's calibrated camera, held fixed (default), or COLMAP's own estimate (an uncalibrated capture)",
    )
    colmap.add_argument(
        "--max-features", type=int, default=8192, metavar="N", help="SIFT features a view at most (8192)"
    )
    colmap.add_argument(
        "--peak-threshold",
        type=float,
        default=0.001,
        metavar="T",
        help="SIFT's contrast threshold: 0.001 for rendered views (default); COLMAP's own is 0.0067",
    )
    colmap.add_argument(
        "--attempts",
        type=int,
        default=3,
        metavar="N",
        help="map again with the next seed while the largest model holds under 90%% of the views, N mappings in "
        "all (3)",
    )
    colmap.add_argument("--seed", type=int, default=0, metavar="N", help="COLMAP's random seed (0)")
    colmap.add_argument("--overwrite", action="store_true", help="replace an existing RUN_DIR/colmap/")


def _view_arguments(view: argparse.ArgumentParser) -> None:
    view.add_argument("target", type=Path, metavar="RUN_DIR|RRD", help="a run's output directory or a recording file")
    web_flags(view)


def _cmd_run(args: argparse.Namespace) -> int:
    from agrisim.episode import Episode
    from agrisim.plugins.apps.progress import EpisodeProgress

    overrides = overrides_from_args(args)
    web = None
    if args.serve_web:
        from agrisim.plugins.apps.web import grpc_url

        web = web_address(args)
        set_dotted(overrides, "sink.rerun.connect", grpc_url(web[0], web[2]))
    elif any(v is not None for v in (args.web_port, args.grpc_port, args.bind)):
        raise UserError("--web-port, --grpc-port and --bind go with --serve-web")
    if args.resume:
        config = _resume_config(args, overrides)
    else:
        base = load_toml(args.config) if args.config else {}
        config = build_config(base, overrides)
    episode = Episode(config)  # validates everything; nothing is written before run()
    for note in getattr(getattr(episode, "plant", None), "notes", []):
        print(f"plant: {note}")
    for note in getattr(episode.rig, "notes", []):
        print(f"rig: {note}")
    viewer = None
    try:
        if web is not None:
            from agrisim.plugins.apps.web import serve_web

            viewer = serve_web(None, *web)
            print(f"watch the run in a browser: {viewer.url}", flush=True)
        with EpisodeProgress() as progress:
            run, summary = episode.run(progress=progress.update)
        _report_run(run, summary)
        if viewer is not None:
            print(
                f"the run is over; still serving it at {viewer.url} (Ctrl-C to stop; agrisim view {run.out_dir} serves it again)",
                flush=True,
            )
            viewer.wait()
    finally:
        if viewer is not None:
            viewer.stop()
    return 0


def _cmd_ros(args: argparse.Namespace) -> int:
    import signal

    from agrisim.config import backend_options
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.plugins.ros.live import LiveSession

    config = build_config(load_toml(args.config) if args.config else {}, overrides_from_args(args))
    session = LiveSession(config, routine=args.routine, real_time_factor=args.real_time_factor)
    name = f"ros{args.ros}"
    spec = session.registry.get("bridge", name)
    options = backend_options(
        spec.options_model, {"rate": args.rate} if args.rate is not None else {}, f"bridge {name!r}"
    )
    if spec.preflight is not None:  # the middleware there, before anything is written
        spec.preflight(config, options)
    bridge = session.registry.build("bridge", spec, session, options)
    # Ctrl-C and SIGTERM end a live session normally: the run is closed and saved. A shell's
    # background job may have started us with SIGINT ignored.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _interrupt)
    run = session.open()
    status, error = "complete", ""
    try:
        session.start()
        bridge.start()
        for line in bridge.describe():
            print(f"  {line}")
        print(f"serving the cell over ROS {args.ros}; views are saved in {run.out_dir} (Ctrl-C to stop)", flush=True)
        if args.routine:
            with EpisodeProgress() as progress:
                session.run_routine(progress=progress.update)
            print("the routine is done; still serving (Ctrl-C to stop)", flush=True)
        session.serve()
    except KeyboardInterrupt:
        pass  # how a live session ends
    except Exception as exc:
        status, error = "failed", f"{type(exc).__name__}: {exc}"
        raise
    finally:
        bridge.close()
        summary = session.close(status, error)
    print(f"stopped: {summary.setpoints} setpoints ({summary.reached} reached); output: {run.out_dir}", flush=True)
    return 0


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _report_run(run: Any, summary: Any) -> None:
    print(f"reached {summary.reached}/{summary.setpoints} setpoints, {summary.collisions} with collisions")
    worst = max((r.ee_error_mm for r in run.results if r.reached and r.ee_error_mm is not None), default=None)
    if worst is not None:
        print(f"worst camera error at a reached setpoint: {worst:.4f} mm")
    for r in run.results:
        if not r.reached:
            print(f"  {r.frame}: {r.reason}")
    stages = ", ".join(f"{k} {v:.1f} s" for k, v in summary.wall_s.items())
    print(f"simulated {summary.sim_time:.1f} s; wall time: {stages}")
    print(f"output: {run.out_dir}" + "".join(f"  {what}: {path}" for what, path in run.outputs.items()), flush=True)


def _cmd_view(args: argparse.Namespace) -> int:
    from agrisim.plugins.apps.web import recording_of, serve_web

    recording = recording_of(args.target)
    bind, web, grpc = web_address(args)
    with serve_web(recording, bind, web, grpc) as viewer:
        print(f"serving {recording} at {viewer.url} (Ctrl-C to stop)", flush=True)
        status = viewer.wait()
    if status not in (0, -2, -15):
        fail(f"the Rerun web viewer stopped with status {status}", status=1)
    return 0


def _cmd_recon(args: argparse.Namespace) -> int:
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.plugins.apps.recon import reconstruct_saved_run

    overrides: dict[str, Any] = {}
    if args.recon:
        set_dotted(overrides, "recon.backend", args.recon)
    apply_sets(overrides, args.set)
    with EpisodeProgress("views") as progress:
        out, metrics = reconstruct_saved_run(args.run_dir, overrides, args.out, args.overwrite, progress.update)
    print(f"reconstructed {metrics['frames']} views with {metrics['recon']}")
    rows = list(metrics["labels"].items())
    # a bench's plants, each alone (its every label: "all")
    rows += [
        (f"{plant} ({doc['frames']} views)", doc["labels"][ALL]) for plant, doc in metrics.get("plants", {}).items()
    ]
    for name, row in rows:
        line = f"  {name}: {row['pixels']:,} labelled pixels, {row['points']:,} points"
        if "fscore" in row:
            scores = ", ".join(f"F@{t}mm {v:.3f}" for t, v in row["fscore"].items())
            line += (
                f", {scores}, Chamfer {row['chamfer_mm']:.2f} mm" if row["chamfer_mm"] is not None else f", {scores}"
            )
        print(line)
    print(f"output: {out / layout.CLOUDS}  {out / layout.METRICS_JSON}")
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from agrisim.plugins.apps.placement import local_gpu_count
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.plugins.apps.render import RenderPlan

    overrides: dict[str, Any] = {}
    apply_sets(overrides, args.set)
    if args.gpus is not None and args.gpus < 1:
        raise UserError(f"--gpus must be 1 or more, got {args.gpus}")
    if len(args.run_dirs) > 1:
        return _render_several(args, overrides)
    plan = RenderPlan(args.run_dirs[0], args.renderer, overrides, args.out, args.overwrite)
    if plan.done:
        print(f"resuming: {len(plan.done)} of {len(plan.frames)} frames already re-rendered")
    # one run goes to Ray when its frames can be shared among GPUs, or a cluster is named
    if args.ray_address is not None or args.gpus is not None or (plan.device != "cpu" and local_gpu_count() > 1):
        return _render_on_ray(args, overrides, [plan])
    with EpisodeProgress("views") as progress:
        out = plan.run(progress.update)
    print(f"re-rendered {len(plan.frames)} frames of {plan.run_dir} with {plan.spec.name}")
    print(f"output: {out}")
    return 0


def _render_several(args: argparse.Namespace, overrides: dict[str, Any]) -> int:
    """``agrisim render RUN1 RUN2 ...``: every run checked first, then re-rendered as Ray tasks."""
    from agrisim.plugins.apps.render import RenderPlan

    if args.out is not None:
        raise UserError("--out names the output of one run; with several, each goes to RUN_DIR-<renderer>")
    if len(set(p.resolve() for p in args.run_dirs)) < len(args.run_dirs):
        raise UserError("a run is named twice")
    plans = [RenderPlan(d, args.renderer, overrides, None, args.overwrite) for d in args.run_dirs]
    return _render_on_ray(args, overrides, plans)


def _render_on_ray(args: argparse.Namespace, overrides: dict[str, Any], plans: list[Any]) -> int:
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.plugins.apps.render import render_runs

    with EpisodeProgress("views") as progress:
        records = render_runs(
            plans, overrides, args.ray_address, progress.update, gpus=args.gpus, gpu_resource=args.gpu_resource
        )
    failed = [r for r in records if "error" in r]
    for r in records:
        parts = len(r["parts"])
        where = f" ({parts} parts on {parts} GPUs)" if parts > 1 else ""
        print(
            f"  {r['run']}: "
            + (f"failed: {r['error']}" if "error" in r else f"{r['frames']} frames{where} -> {r['out']}")
        )
    if failed:
        fail(f"{len(failed)} of {len(records)} re-renders failed; run the command again to resume them", status=1)
    return 0


def _resume_config(args: argparse.Namespace, overrides: dict[str, Any]) -> RunConfig:
    """The saved configuration of the run in --out, with the output flags of this command.

    The command that started the run, with ``--resume`` appended, continues it: every setting it
    gives (flags, ``--set``, ``--config``) must equal the saved one; the first that differs is
    refused, naming it.
    """
    from agrisim.files.rundir import saved_run

    if args.overwrite:
        raise UserError("--overwrite and --resume exclude each other")
    if args.out is None:
        raise UserError("--resume needs --out DIR: the run to continue")
    saved_doc = saved_run(args.out)["config"]
    base = load_toml(args.config) if args.config else {}
    # This command's settings layered over the saved ones: what it leaves out is the run's own,
    # what it gives must agree (aliases such as --shadow-samples resolved against the saved
    # plant and renderer). Where it goes and who watches may change.
    resumed = build_config(
        saved_doc, base, overrides, {"output": {"out": str(args.out), "resume": True, "overwrite": False}}
    )
    diff = first_difference(outcome_settings(build_config(saved_doc)), outcome_settings(resumed))
    if diff is not None:
        key, was, now = diff
        raise UserError(
            f"--resume: the run in {args.out} was made with {key} = {was!r}, this command asks for "
            f"{now!r}; give the run's own settings (or leave them out) to continue it"
        )
    return resumed


def _cmd_export(args: argparse.Namespace) -> int:
    from agrisim.files.exports import build_exporter, run_export
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.registry import Registry, make_plugin_manager

    registry = Registry(make_plugin_manager())
    installed = registry.specs("exporter")
    if args.format not in installed:
        choices = ", ".join(installed) or "none: no exporter is installed"
        raise UserError(f"argument NAME: invalid choice: {args.format!r} (choose from {choices})")
    spec, exporter = build_exporter(registry, args.format, _export_options(args.format, args.set))
    with EpisodeProgress(exporter.progress_unit or "export") as progress:
        report = progress.update if exporter.progress_unit else None
        written = run_export(spec, exporter, args.run_dir, args.out, args.overwrite, report)
    print(exporter.summary(written))
    return 0


def _export_options(name: str, items: Sequence[str]) -> dict[str, Any]:
    """``--set exporter.NAME.KEY=VALUE`` items: the options of exporter ``name``."""
    options: dict[str, Any] = {}
    prefix = f"exporter.{name}."
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key.startswith(prefix) or key == prefix:
            raise UserError(
                f"--set {item!r}: agrisim export {name} takes its exporter's options, {prefix}KEY=VALUE "
                "(agrisim plugins --options lists them)"
            )
        set_dotted(options, key[len(prefix) :], parse_value(value.strip()))
    return options


def _cmd_colmap(args: argparse.Namespace) -> int:
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.plugins.poses.colmap.photogrammetry import run_colmap

    with EpisodeProgress("features") as progress:
        result = run_colmap(
            args.run_dir,
            matcher=args.matcher,
            intrinsics=args.intrinsics,
            priors=args.priors,
            prior_std_mm=args.prior_std_mm,
            overlap=args.overlap,
            max_features=args.max_features,
            peak_threshold=args.peak_threshold,
            attempts=args.attempts,
            seed=args.seed,
            overwrite=args.overwrite,
            progress=progress.stage,
        )
    s = result.summary()
    if not result.models:
        print(f"COLMAP made no model of the {s['views']} views (too few views matched well enough to start one)")
    else:
        if result.models == 1:
            models = "one model"
        elif result.settings["priors"] == "robot":
            models = f"{result.models} models, each held to the robot's priors"
        else:
            models = f"{result.models} models, the largest kept"
        print(
            f"COLMAP registered {s['registered']} of {s['views']} views ({models}: {s['points']:,} points); "
            f"{s['within_20mm']} within 20 mm of the truth"
        )
        if len(result.attempts) > 1:
            tried = ", ".join(f"seed {a['seed']}: {a['registered']}" for a in result.attempts)
            print(f"mapped {len(result.attempts)} times while too few views were placed ({tried})")
    if s["median_centre_error_mm"] is not None:
        print(
            f"camera centres from the truth: median {s['median_centre_error_mm']:.2f} mm, max "
            f"{s['max_centre_error_mm']:.2f} mm; rotations: median {s['median_rotation_error_deg']:.3f} deg, max "
            f"{s['max_rotation_error_deg']:.3f} deg; reprojection {s['reprojection_px']:.2f} px"
        )
    print(f"wrote {result.out}")
    return 0


#: this module's commands, each its flags and its function
COMMANDS = [
    Command(
        "run",
        help="run one episode of the routine",
        description="Run one episode of the routine.",
        add_arguments=_run_arguments,
        run=_cmd_run,
    ),
    Command(
        "ros",
        help="serve the cell live over ROS 1 or ROS 2: trajectories in, views on a trigger, topics out",
        description="Serve a live session of the cell (loaded as agrisim run loads it) over ROS: joint "
        "trajectories in, views on a trigger, joint states, TF and images out; every view saved to --out.",
        add_arguments=_ros_arguments,
        run=_cmd_ros,
    ),
    Command(
        "recon",
        help="rebuild a run's reconstruction and metrics from its files",
        description="Rebuild the reconstruction (clouds/) and metrics.json of a complete run from its images.",
        add_arguments=_recon_arguments,
        run=_cmd_recon,
    ),
    Command(
        "render",
        help="re-render a finished run's RGB with another renderer (e.g. path-traced), keeping its labels and depth",
        description="Draw the RGB of a complete run again from its saved scene, camera and arm poses, into a complete "
        "dataset (default: RUN_DIR-<renderer>); labels, depth, instances, clouds and metrics are carried over.",
        add_arguments=_render_arguments,
        run=_cmd_render,
    ),
    Command(
        "export",
        help="export a run directory to another tool's format (an exporter: agrisim plugins lists them)",
        description="Export a run directory with an exporter (agrisim plugins lists the installed ones, with "
        "their options): nerfstudio writes RUN_DIR/transforms.json and RUN_DIR/masks/; "
        "coco writes RUN_DIR/coco/annotations.json (COCO instance masks); rosbag writes RUN_DIR/rosbag/ "
        "(a ROS 2 bag in MCAP: TF, joint states, planned trajectories, camera images, depth, labels, clouds). "
        "OUT puts the export elsewhere (coco: the JSON file; rosbag: the bag's folder; nerfstudio takes none).",
        add_arguments=_export_arguments,
        run=_cmd_export,
    ),
    Command(
        "colmap",
        help="COLMAP's structure from motion on a run's views, scored against the true cameras",
        description="Recover the cameras of a complete run's RGB views with COLMAP (pycolmap, CPU): SIFT features, "
        "matching, incremental mapping; align the model to the true camera centres by a similarity and score each "
        "view (centre error, rotation error, reprojection error). Writes RUN_DIR/colmap/ (sparse/0/, poses.json).",
        add_arguments=_colmap_arguments,
        run=_cmd_colmap,
    ),
    Command(
        "view",
        help="serve a run's Rerun recording to a web browser",
        description="Serve a run's recording (RUN_DIR/recording.rrd, or an .rrd file) with Rerun's web viewer and "
        "print the address to open; Ctrl-C stops. Loopback only unless --bind says otherwise.",
        add_arguments=_view_arguments,
        run=_cmd_view,
    ),
]
