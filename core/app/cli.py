"""The ``agrisim`` command line: ``agrisim run``, ``agrisim plants`` and ``agrisim plugins``.

Bad input exits with status 2 and one line naming the problem; nothing is written. Internal
failures exit 1 (``AGRISIM_DEBUG=1`` shows the traceback) with the run's partial results kept.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from agrisim.files import layout
from agrisim.config import RunConfig, build_config, first_difference, load_toml, outcome_settings
from agrisim.errors import BackendFailure, UserError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PROG = "agrisim"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump), exit status 2."""

    def error(self, message: str) -> NoReturn:
        _fail(message)


def _fail(message: str, status: int = 2) -> NoReturn:
    sys.stderr.write(f"{PROG}: error: {message}\n")
    raise SystemExit(status)


# Long but flat: one declaration per flag, the CLI's reference in one place.
def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description="Robot arms photographing plants: simulate, annotate, reconstruct.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    run = sub.add_parser("run", help="run one episode of the routine", description="Run one episode of the routine.")
    run.add_argument("--config", type=Path, metavar="TOML", help="configuration file; flags override it")
    run.add_argument("--plant", metavar="NAME|PATH", help="species (agrisim plants), a .glb/.gltf/.obj mesh or a .ply/.pcd point cloud")
    run.add_argument("--plant-age", type=float, metavar="DAYS", help="age of a growing plant (helios:*), days")
    run.add_argument(
        "--as-points", type=int, metavar="N", help="draw the plant as N points sampled on its opaque surface (the paper's Table 3)"
    )
    run.add_argument(
        "--point-size", type=float, metavar="M", help="diameter of each point of a point plant, metres (default: one that covers its surface)"
    )
    run.add_argument("--seg-mode", choices=["texture", "repopa"], help="segmentation mode (default: texture)")
    run.add_argument("--labels", choices=["plant", "organs"], help="one plant label, or one per organ (default: plant)")
    run.add_argument("--renderer", metavar="NAME", help="renderer (default: raycast; none: robots only)")
    run.add_argument("--shadow-samples", type=int, metavar="N", help="shadow rays per pixel, 0..32 (default: 1)")
    run.add_argument("--supersample", type=int, metavar="S", help="S x S RGB rays per pixel, 1..4 (default: 1)")
    run.add_argument("--hide-robots", action="store_true", default=None, help="render without the arms")
    run.add_argument(
        "--depth-format", choices=["png16", "exr", "both"], help="depth as uint16 mm PNG, float32 m EXR, or both (default: png16)"
    )
    run.add_argument("--pcg-seed", type=int, metavar="N", help="seed of the lab clutter (default: 42)")
    run.add_argument("--physics", metavar="NAME", help="physics backend (default: pybullet)")
    run.add_argument("--planner", metavar="NAME", help="motion planner (default: ompl)")
    run.add_argument("--recon", metavar="NAME", help="reconstructor (default: pointcloud; none: no reconstruction)")
    run.add_argument("--camera", metavar="PRESET", help="camera preset (default: rpi3-wide-1080p)")
    run.add_argument("--resolution", metavar="WxH", help="image size (default: the preset's 1920x1080)")
    run.add_argument("--setpoints", metavar="LxC", help="L levels x C columns per arm (default: 5x10)")
    run.add_argument("--setpoints-csv", type=Path, metavar="CSV", help="camera poses from a CSV instead")
    run.add_argument("--arms", type=int, metavar="N", help="1 or 2 arms (default: 2)")
    run.add_argument("--seed", type=int, metavar="N", help="seed for IK restarts and planners (default: 0)")
    run.add_argument("--out", type=Path, metavar="DIR", help="output directory (default: runs/<timestamp>)")
    rec = run.add_mutually_exclusive_group()
    rec.add_argument("--rrd", type=Path, metavar="PATH", help="Rerun recording path (default: OUT/recording.rrd)")
    rec.add_argument("--no-rrd", action="store_true", default=None, help="write no Rerun recording")
    run.add_argument("--spawn", action="store_true", default=None, help="stream to a spawned Rerun viewer")
    run.add_argument(
        "--serve-web",
        action="store_true",
        help="stream the run live to Rerun's web viewer, served here (print its address; after the run, serve until Ctrl-C)",
    )
    _web_flags(run)
    run.add_argument("--overwrite", action="store_true", default=None, help="replace an existing --out")
    run.add_argument(
        "--resume",
        action="store_true",
        default=None,
        help="continue the unfinished run in --out with its saved configuration",
    )
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="any setting by its dotted name, e.g. physics.pybullet.position_gain=0.5",
    )

    plants = sub.add_parser("plants", help="list the plant species: triangles, organs, area cut away by opacity")
    plants.add_argument("--seed", type=int, default=0, metavar="N", help="seed to grow each species with (0)")
    plugins = sub.add_parser("plugins", help="list every backend of every kind and where it comes from")
    plugins.add_argument("--options", action="store_true", help="also list each backend's options")
    recon = sub.add_parser(
        "recon",
        help="rebuild a run's reconstruction and metrics from its files",
        description="Rebuild the reconstruction (clouds/) and metrics.json of a complete run from its images.",
    )
    recon.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a complete run's output directory")
    recon.add_argument("--recon", metavar="NAME", help="reconstructor (default: the run's own)")
    recon.add_argument("--out", type=Path, metavar="DIR", help="write clouds/ and metrics.json here (default: RUN_DIR)")
    recon.add_argument("--overwrite", action="store_true", help="replace existing clouds and metrics.json")
    recon.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="recon.* or metrics.* settings, e.g. recon.tsdf.voxel_size=0.003",
    )
    render = sub.add_parser(
        "render",
        help="re-render a finished run's RGB with another renderer (e.g. path-traced), keeping its labels and depth",
        description="Draw the RGB of a complete run again from its saved scene, camera and arm poses, into a complete "
        "dataset (default: RUN_DIR-<renderer>); labels, depth, instances, clouds and metrics are carried over.",
    )
    render.add_argument("run_dirs", type=Path, nargs="+", metavar="RUN_DIR", help="complete runs' output directories")
    render.add_argument("--renderer", default="mitsuba", metavar="NAME", help="a renderer that can re-render (mitsuba)")
    render.add_argument("--out", type=Path, metavar="DIR", help="output directory of one run (default: RUN_DIR-<renderer>)")
    render.add_argument(
        "--ray-address", metavar="ADDR", help="several runs: join this Ray cluster (default: a local one), one GPU a run"
    )
    render.add_argument("--overwrite", action="store_true", help="replace an existing --out (or RUN_DIR's own RGB)")
    render.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="renderer.* settings, e.g. renderer.mitsuba.spp=64"
    )
    export = sub.add_parser(
        "export",
        help="export a run directory to another tool's format",
        description="Export a run directory: nerfstudio writes RUN_DIR/transforms.json and RUN_DIR/masks/; "
        "coco writes RUN_DIR/coco/annotations.json (COCO instance masks); rosbag writes RUN_DIR/rosbag/ "
        "(a ROS 2 bag in MCAP: TF, joint states, planned trajectories, camera images, depth, labels, clouds).",
    )
    export.add_argument(
        "format", choices=["nerfstudio", "coco", "rosbag"], help="the format: nerfstudio (transforms.json), coco or rosbag"
    )
    export.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run's output directory (agrisim run --out)")
    export.add_argument("--overwrite", action="store_true", help="replace an existing export (coco, rosbag)")
    view = sub.add_parser(
        "view",
        help="serve a run's Rerun recording to a web browser",
        description="Serve a run's recording (RUN_DIR/recording.rrd, or an .rrd file) with Rerun's web viewer and "
        "print the address to open; Ctrl-C stops. Loopback only unless --bind says otherwise.",
    )
    view.add_argument("target", type=Path, metavar="RUN_DIR|RRD", help="a run's output directory or a recording file")
    _web_flags(view)
    compare = sub.add_parser(
        "compare",
        help="the paper's Table 2: every plant in both segmentation modes, episodes on Ray",
        description="Run every plant in both segmentation modes (texture, repopa) as Ray tasks, each into "
        "OUT/<plant>/<seg_mode>, and write the paper's Table 2 with accuracy: OUT/table.md, table.csv, chart.png.",
    )
    compare.add_argument("--plants", metavar="A,B,...", help="species or plant files (default: the ten species)")
    compare.add_argument("--seg-modes", metavar="M,...", help="segmentation modes (default: texture,repopa)")
    compare.add_argument(
        "--as-points", type=int, metavar="N", help="with --point-sizes: each plant as N points sampled on its surface"
    )
    compare.add_argument(
        "--point-sizes",
        metavar="M,...",
        help="the paper's Table 3: the mesh, then its points at each size (diameters in metres, e.g. 0.001,0.002)",
    )
    compare.add_argument("--workers", type=int, metavar="N", help="episodes at a time (default: one per CPU)")
    compare.add_argument(
        "--ray-address", metavar="ADDR", help="join this Ray cluster (HOST:PORT or auto; default: a local Ray)"
    )
    compare.add_argument("--out", type=Path, metavar="DIR", help="output directory (default: runs/compare-<timestamp>)")
    compare.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    compare.add_argument("--resume", action="store_true", help="continue the compare in --out: complete runs are kept")
    compare.add_argument("--recordings", action="store_true", help="also write each episode's recording.rrd")
    compare.add_argument("--config", type=Path, metavar="TOML", help="configuration file shared by the episodes")
    for flag, meta, kind, text in _COMPARE_EPISODE_FLAGS:
        compare.add_argument(flag, metavar=meta, type=kind, help=text)
    compare.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="any setting by its dotted name"
    )
    return p


#: the episode options `compare` passes on (as `agrisim run` has them)
_COMPARE_EPISODE_FLAGS: list[tuple[str, str, Any, str]] = [
    ("--labels", "plant|organs", str, "one plant label, or one per organ (default: plant)"),
    ("--plant-age", "DAYS", float, "age of every growing plant (helios:*), days (default: each model's)"),
    ("--renderer", "NAME", str, "renderer (default: raycast)"),
    ("--shadow-samples", "N", int, "shadow rays per pixel, 0..32 (default: 1)"),
    ("--physics", "NAME", str, "physics backend (default: pybullet)"),
    ("--planner", "NAME", str, "motion planner (default: ompl)"),
    ("--recon", "NAME", str, "reconstructor (default: pointcloud)"),
    ("--camera", "PRESET", str, "camera preset (default: rpi3-wide-1080p)"),
    ("--resolution", "WxH", str, "image size (default: the preset's 1920x1080)"),
    ("--setpoints", "LxC", str, "L levels x C columns per arm (default: 5x10)"),
    ("--seed", "N", int, "seed for IK restarts and planners (default: 0)"),
    ("--pcg-seed", "N", int, "seed of the lab clutter (default: 42)"),
]


def _set(tree: dict[str, Any], dotted: str, value: Any) -> None:
    keys = dotted.split(".")
    node = tree
    for key in keys[:-1]:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise UserError(f"--set {dotted}: {key!r} is not a table")
    node[keys[-1]] = value


def _parse_value(text: str) -> Any:
    """A TOML value (number, bool, string, array); bare words are strings, and so are words
    like ``0x1`` that TOML would read as hexadecimal, octal or binary numbers (a grid ``LxC``)."""
    if re.fullmatch(r"[+-]?0[xob][0-9a-fA-F_]*", text.strip()):
        return text
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _web_flags(parser: argparse.ArgumentParser) -> None:
    from agrisim.app.web import DEFAULT_BIND, DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT

    parser.add_argument("--web-port", type=int, metavar="N", help=f"port of the web page (default: {DEFAULT_WEB_PORT})")
    parser.add_argument("--grpc-port", type=int, metavar="N", help=f"port the page reads the recording from (default: {DEFAULT_GRPC_PORT})")
    parser.add_argument("--bind", metavar="ADDR", help=f"address to serve on (default: {DEFAULT_BIND}, this machine only; 0.0.0.0: every interface)")


def _web_address(args: argparse.Namespace) -> tuple[str, int, int]:
    """(bind, web port, gRPC port) of ``--bind``, ``--web-port``, ``--grpc-port``, checked."""
    from agrisim.app.web import DEFAULT_BIND, DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT, check_address

    bind = args.bind or DEFAULT_BIND
    web = args.web_port if args.web_port is not None else DEFAULT_WEB_PORT
    grpc = args.grpc_port if args.grpc_port is not None else DEFAULT_GRPC_PORT
    if web == grpc:
        raise UserError(f"--web-port and --grpc-port must differ (both {web})")
    check_address(bind, {"--web-port": web, "--grpc-port": grpc})
    return bind, web, grpc


def overrides_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """The flags given on the command line, as a nested config dictionary."""
    out: dict[str, Any] = {}
    flat = {
        "plant": args.plant,
        "plant_age": args.plant_age,
        "points.count": args.as_points,
        "points.size": args.point_size,
        "render.seg_mode": args.seg_mode,
        "render.labels": args.labels,
        "renderer.backend": args.renderer,
        "render.shadow_samples": args.shadow_samples,
        "render.supersample": args.supersample,
        "render.hide_robots": args.hide_robots,
        "render.depth_format": args.depth_format,
        "pcg_seed": args.pcg_seed,
        "physics.backend": args.physics,
        "planner.backend": args.planner,
        "recon.backend": args.recon,
        "camera.preset": args.camera,
        "camera.resolution": args.resolution,
        "routine.setpoints": args.setpoints,
        "routine.csv": str(args.setpoints_csv) if args.setpoints_csv else None,
        "cell.arms": args.arms,
        "seed": args.seed,
        "output.out": str(args.out) if args.out else None,
        "output.rrd": str(args.rrd) if args.rrd else None,
        "output.no_rrd": args.no_rrd,
        "output.spawn": args.spawn,
        "output.overwrite": args.overwrite,
        "output.resume": args.resume,
    }
    for key, value in flat.items():
        if value is not None:
            _set(out, key, value)
    _apply_sets(out, args.set)
    return out


def _apply_sets(tree: dict[str, Any], items: Sequence[str]) -> None:
    """``--set KEY=VALUE`` items into a nested config dictionary."""
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set expects KEY=VALUE, got {item!r}")
        _set(tree, key.strip(), _parse_value(value.strip()))


def _cmd_run(args: argparse.Namespace) -> int:
    from agrisim.episode import Episode
    from agrisim.app.progress import EpisodeProgress

    overrides = overrides_from_args(args)
    web = None
    if args.serve_web:
        from agrisim.app.web import grpc_url

        web = _web_address(args)
        _set(overrides, "sink.rerun.connect", grpc_url(web[0], web[2]))
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
    viewer = None
    try:
        if web is not None:
            from agrisim.app.web import serve_web

            viewer = serve_web(None, *web)
            print(f"watch the run in a browser: {viewer.url}", flush=True)
        with EpisodeProgress() as progress:
            run, summary = episode.run(progress=progress.update)
        _report_run(run, summary)
        if viewer is not None:
            print(f"the run is over; still serving it at {viewer.url} (Ctrl-C to stop; agrisim view {run.out_dir} serves it again)", flush=True)
            viewer.wait()
    finally:
        if viewer is not None:
            viewer.stop()
    return 0


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
    from agrisim.app.web import recording_of, serve_web

    recording = recording_of(args.target)
    bind, web, grpc = _web_address(args)
    with serve_web(recording, bind, web, grpc) as viewer:
        print(f"serving {recording} at {viewer.url} (Ctrl-C to stop)", flush=True)
        status = viewer.wait()
    if status not in (0, -2, -15):
        _fail(f"the Rerun web viewer stopped with status {status}", status=1)
    return 0


def _cmd_recon(args: argparse.Namespace) -> int:
    from agrisim.app.progress import EpisodeProgress
    from agrisim.evaluation.session import reconstruct_saved_run

    overrides: dict[str, Any] = {}
    if args.recon:
        _set(overrides, "recon.backend", args.recon)
    _apply_sets(overrides, args.set)
    with EpisodeProgress("views") as progress:
        out, metrics = reconstruct_saved_run(args.run_dir, overrides, args.out, args.overwrite, progress.update)
    print(f"reconstructed {metrics['frames']} views with {metrics['recon']}")
    for name, row in metrics["labels"].items():
        line = f"  {name}: {row['pixels']:,} labelled pixels, {row['points']:,} points"
        if "fscore" in row:
            scores = ", ".join(f"F@{t}mm {v:.3f}" for t, v in row["fscore"].items())
            line += f", {scores}, Chamfer {row['chamfer_mm']:.2f} mm" if row["chamfer_mm"] is not None else f", {scores}"
        print(line)
    print(f"output: {out / layout.CLOUDS}  {out / layout.METRICS_JSON}")
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from agrisim.app.progress import EpisodeProgress
    from agrisim.app.render import RenderPlan

    overrides: dict[str, Any] = {}
    _apply_sets(overrides, args.set)
    if len(args.run_dirs) > 1:
        return _render_several(args, overrides)
    plan = RenderPlan(args.run_dirs[0], args.renderer, overrides, args.out, args.overwrite)
    if plan.done:
        print(f"resuming: {len(plan.done)} of {len(plan.frames)} frames already re-rendered")
    with EpisodeProgress("views") as progress:
        out = plan.run(progress.update)
    print(f"re-rendered {len(plan.frames)} frames of {plan.run_dir} with {plan.spec.name}")
    print(f"output: {out}")
    return 0


def _render_several(args: argparse.Namespace, overrides: dict[str, Any]) -> int:
    """``agrisim render RUN1 RUN2 ...``: every run checked first, then re-rendered as Ray tasks."""
    from agrisim.app.progress import EpisodeProgress
    from agrisim.app.render import RenderPlan, render_runs

    if args.out is not None:
        raise UserError("--out names the output of one run; with several, each goes to RUN_DIR-<renderer>")
    if len(set(p.resolve() for p in args.run_dirs)) < len(args.run_dirs):
        raise UserError("a run is named twice")
    plans = [RenderPlan(d, args.renderer, overrides, None, args.overwrite) for d in args.run_dirs]
    with EpisodeProgress("runs") as progress:
        records = render_runs(plans, overrides, args.overwrite, args.ray_address, progress.update)
    failed = [r for r in records if "error" in r]
    for r in records:
        print(f"  {r['run']}: " + (f"failed: {r['error']}" if "error" in r else f"{r['frames']} frames -> {r['out']}"))
    if failed:
        _fail(f"{len(failed)} of {len(records)} re-renders failed; run the command again to resume them", status=1)
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
    resumed = build_config(saved_doc, base, overrides, {"output": {"out": str(args.out), "resume": True, "overwrite": False}})
    diff = first_difference(outcome_settings(build_config(saved_doc)), outcome_settings(resumed))
    if diff is not None:
        key, was, now = diff
        raise UserError(
            f"--resume: the run in {args.out} was made with {key} = {was!r}, this command asks for "
            f"{now!r}; give the run's own settings (or leave them out) to continue it"
        )
    return resumed


def _cmd_plugins(args: argparse.Namespace) -> int:
    from agrisim.capabilities import describe
    from agrisim.registry import PROVIDER_HOOKS, Registry, make_plugin_manager

    registry = Registry(make_plugin_manager())
    for kind in PROVIDER_HOOKS:
        specs = registry.specs(kind)
        print(f"{kind}:")
        if not specs:
            print("  (none installed)")
        width = max((len(n) for n in specs), default=0)
        for name, spec in specs.items():
            print(f"  {name:<{width}}  {spec.description}  [{spec.distribution}]")
            if spec.limits:
                print(f"  {'':<{width}}  limits: {spec.limits}")
            if spec.capabilities is not None:
                print(f"  {'':<{width}}  can: {describe(spec.capabilities)}")
            if args.options:
                for field, info in spec.options_model.model_fields.items():
                    doc = (info.description or "").replace("\n", " ")
                    print(f"  {'':<{width}}    {kind}.{name}.{field} = {info.default!r}  {doc}")
    return 0


def _cmd_plants(args: argparse.Namespace) -> int:
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.scene.texturing import cutaway_fraction

    if args.seed < 0:
        raise UserError(f"--seed must be 0 or more, got {args.seed}")
    registry = Registry(make_plugin_manager())
    specs = registry.specs("plant")
    if not specs:
        print("no plant species installed")
        return 0
    width = max(len(n) for n in specs)
    print(f"{'species':<{width}}  {'triangles':>9}  {'cut away':>8}  labels  [distribution]")
    for name, spec in specs.items():
        plant = registry.build("plant", spec, spec.options_model()).build(args.seed)
        organs = ", ".join(lab.name for lab in plant.labels.labels if lab.id)
        cut = cutaway_fraction(plant.mesh, samples=100_000)
        print(f"{name:<{width}}  {len(plant.mesh.faces):>9,}  {cut:>7.1%}  {organs}  [{spec.distribution}]")
    print("cut away: share of the plant's surface area that opacity removes (what RepOpa labels wrongly)")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    if args.format == "rosbag":
        from agrisim.app.progress import EpisodeProgress
        from agrisim.files.rosbag import write_rosbag

        with EpisodeProgress("stamps and frames") as progress:
            out = write_rosbag(args.run_dir, args.overwrite, progress.update)
        print(f"wrote {out} (ros2 bag info {out}; open {out / 'rosbag.mcap'} in Foxglove)")
        return 0
    if args.format == "coco":
        from agrisim.files.coco import write_coco

        out = write_coco(args.run_dir, args.overwrite)
        print(f"wrote {out}")
        return 0
    from agrisim.files.nerfstudio import write_nerfstudio

    out = write_nerfstudio(args.run_dir)
    print(f"wrote {out}")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from agrisim.app.compare import SEG_MODES, compare, default_out, markdown_table, parse_names, plan_compare
    from agrisim.app.compare_plan import parse_sizes
    from agrisim.app.point_table import point_markdown
    from agrisim.config import merge
    from agrisim.app.progress import EpisodeProgress

    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be 1 or more, got {args.workers}")
    # Every `run` option at its default, then compare's episode options on top: the overrides
    # are built exactly as for `agrisim run`.
    episode = _parser().parse_args(["run"])
    for flag, *_ in _COMPARE_EPISODE_FLAGS:
        dest = flag.lstrip("-").replace("-", "_")
        setattr(episode, dest, getattr(args, dest))
    episode.set = args.set
    base = merge(load_toml(args.config) if args.config else {}, overrides_from_args(episode))
    plan = plan_compare(
        base,
        out=args.out or default_out(),
        plants=parse_names(args.plants, "plants"),
        seg_modes=parse_names(args.seg_modes, "seg-modes", SEG_MODES),
        overwrite=args.overwrite,
        resume=args.resume,
        recordings=args.recordings,
        as_points=args.as_points,
        point_sizes=parse_sizes(args.point_sizes),
    )  # validates everything before Ray starts or anything is written
    with EpisodeProgress("episodes") as progress:
        result = compare(plan, workers=args.workers, ray_address=args.ray_address, progress=progress.update)
    print(point_markdown(result.rows) if plan.point_sizes else markdown_table(result.rows, plan.seg_modes), end="")
    ran = [r for r in result.records if r.get("status") != "skipped"]
    kept = len(result.records) - len(ran)
    if ran:
        if args.workers:
            at_a_time = f"{args.workers} at a time"
        else:
            at_a_time = "one per CPU" if args.ray_address is None else "as many at a time as the cluster allows"
        where = f"{result.ray.get('address')}, {at_a_time}"
        were = f", {kept} {'was' if kept == 1 else 'were'} complete already" if kept else ""
        print(
            f"{len(ran)} episodes ran as Ray tasks ({where}){were}; "
            f"wall time {result.wall_s:.1f} s (Ray start {result.ray.get('startup_s', 0):.1f} s)"
        )
    else:
        print(f"all {kept} episodes were complete already: the table is rebuilt from their run directories")
    print(f"output: {result.paths['md']}  {result.paths['csv']}  {result.paths['png']}")
    for r in result.failed:
        sys.stderr.write(f"{PROG}: {r['plant']} ({r.get('variant') or r['seg_mode']}) {r['status']}: {r.get('error', '')}\n")
    if result.failed or result.missing:
        _fail(f"{len(result.failed)} of {len(result.records)} episodes did not complete; "
              f"the table lacks {', '.join(result.missing) or 'nothing'}; --resume continues", status=1)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``agrisim`` console script."""
    args = _parser().parse_args(argv)
    try:
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "plants":
            return _cmd_plants(args)
        if args.command == "recon":
            return _cmd_recon(args)
        if args.command == "export":
            return _cmd_export(args)
        if args.command == "render":
            return _cmd_render(args)
        if args.command == "compare":
            return _cmd_compare(args)
        if args.command == "view":
            return _cmd_view(args)
        return _cmd_plugins(args)
    except UserError as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted\n")
        return 130
    except BrokenPipeError:  # output piped into `head` and the like
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except BackendFailure as exc:  # a plugin's failure: named, the run's finished work kept
        _fail(str(exc), status=1)
    except Exception as exc:  # an internal failure, not the user's input
        if os.environ.get("AGRISIM_DEBUG"):
            traceback.print_exc()
        _fail(f"internal error: {type(exc).__name__}: {exc} (set AGRISIM_DEBUG=1 for the traceback)", status=1)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
