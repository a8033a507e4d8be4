"""The ``agrisim`` commands: ``run``, ``ros``, ``view``, ``recon``, ``render``, ``plugins``,
``doctor``, ``plants``, ``export``, ``compare``, ``sweep`` and ``colmap``, each a function of its parsed flags (:mod:`agrisim.app.arguments`
declares them).

Bad input exits with status 2 and one line naming the problem; nothing is written. Internal
failures exit 1 (``AGRISIM_DEBUG=1`` shows the traceback) with the run's partial results kept.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
from collections.abc import Sequence
from typing import Any

from agrisim.app.arguments import (
    COMPARE_EPISODE_FLAGS,
    PROG,
    apply_sets,
    build_parser,
    fail,
    overrides_from_args,
    parse_value,
    set_dotted,
    web_address,
)
from agrisim.config import RunConfig, build_config, first_difference, load_toml, outcome_settings
from agrisim.errors import BackendFailure, UserError
from agrisim.files import layout


def _cmd_run(args: argparse.Namespace) -> int:
    from agrisim.app.progress import EpisodeProgress
    from agrisim.episode import Episode

    overrides = overrides_from_args(args)
    web = None
    if args.serve_web:
        from agrisim.app.web import grpc_url

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

    from agrisim.app.progress import EpisodeProgress
    from agrisim.config import backend_options
    from agrisim.live import LiveSession

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
    from agrisim.app.web import recording_of, serve_web

    recording = recording_of(args.target)
    bind, web, grpc = web_address(args)
    with serve_web(recording, bind, web, grpc) as viewer:
        print(f"serving {recording} at {viewer.url} (Ctrl-C to stop)", flush=True)
        status = viewer.wait()
    if status not in (0, -2, -15):
        fail(f"the Rerun web viewer stopped with status {status}", status=1)
    return 0


def _cmd_recon(args: argparse.Namespace) -> int:
    from agrisim.app.progress import EpisodeProgress
    from agrisim.evaluation.session import reconstruct_saved_run

    overrides: dict[str, Any] = {}
    if args.recon:
        set_dotted(overrides, "recon.backend", args.recon)
    apply_sets(overrides, args.set)
    with EpisodeProgress("views") as progress:
        out, metrics = reconstruct_saved_run(args.run_dir, overrides, args.out, args.overwrite, progress.update)
    print(f"reconstructed {metrics['frames']} views with {metrics['recon']}")
    for name, row in metrics["labels"].items():
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
    from agrisim.app.placement import local_gpu_count
    from agrisim.app.progress import EpisodeProgress
    from agrisim.app.render import RenderPlan

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
    from agrisim.app.render import RenderPlan

    if args.out is not None:
        raise UserError("--out names the output of one run; with several, each goes to RUN_DIR-<renderer>")
    if len(set(p.resolve() for p in args.run_dirs)) < len(args.run_dirs):
        raise UserError("a run is named twice")
    plans = [RenderPlan(d, args.renderer, overrides, None, args.overwrite) for d in args.run_dirs]
    return _render_on_ray(args, overrides, plans)


def _render_on_ray(args: argparse.Namespace, overrides: dict[str, Any], plans: list[Any]) -> int:
    from agrisim.app.progress import EpisodeProgress
    from agrisim.app.render import render_runs

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


def _cmd_doctor(args: argparse.Namespace) -> int:
    import json

    from agrisim.app.doctor import gather, render_text

    report = gather(timing=not args.no_timing)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        for line in render_text(report):
            print(line)
    return 0 if report["default_run"]["ok"] else 1


def _cmd_plants(args: argparse.Namespace) -> int:
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.scene.plant_cache import grown
    from agrisim.scene.texturing import surface_summary

    if args.seed < 0:
        raise UserError(f"--seed must be 0 or more, got {args.seed}")
    registry = Registry(make_plugin_manager())
    specs = registry.specs("plant")
    if not specs:
        print("no plant species installed")
        return 0
    width = max(len(n) for n in specs)
    print(
        f"{'species':<{width}}  {'triangles':>9}  {'cut away':>8}  {'leaves':>6}  {'leaf cm^2':>9}  labels  [distribution]"
    )
    for name, spec in specs.items():
        options = spec.options_model()
        plant = grown(name, options, args.seed, registry.build("plant", spec, options).build)
        organs = ", ".join(lab.name for lab in plant.labels.labels if lab.id)
        cut, leaves, leaf_area = surface_summary(plant.mesh, samples=100_000)
        print(
            f"{name:<{width}}  {len(plant.mesh.faces):>9,}  {cut:>7.1%}  {leaves:>6}  {leaf_area * 1e4:>9.0f}  "
            f"{organs}  [{spec.distribution}]"
        )
    print("cut away: share of the plant's surface area that opacity removes (what RepOpa labels wrongly)")
    print("leaves: leaf instances; leaf cm^2: their opaque area, sampled (agrisim traits SPECIES: exact, leaf by leaf)")
    return 0


def _cmd_traits(args: argparse.Namespace) -> int:
    from pathlib import Path

    from agrisim.app.progress import EpisodeProgress
    from agrisim.errors import OutputError
    from agrisim.files.atomic import write_json
    from agrisim.files.rundir import read_json
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.scene.plant_choice import check_plant_name, resolve_plant
    from agrisim.traits.document import traits_document
    from agrisim.traits.estimate import measurable_frames, measure
    from agrisim.traits.truth import plant_traits

    target = Path(args.target)
    if args.seed is not None and args.seed < 0:
        raise UserError(f"--seed must be 0 or more, got {args.seed}")
    registry = Registry(make_plugin_manager())
    if target.is_dir():
        run = read_json(target / layout.RUN_JSON, "not an agrisim run (no run.json)")
        if args.seed is not None:
            raise UserError("--seed applies to a species, not to a run (a run's plant has the run's seed)")
        config = build_config(run["config"])
        out = args.out or target / "traits.json"
        if args.measure:
            measurable_frames(target, run)
    else:
        if args.measure:
            raise UserError(f"--measure needs a run's directory (its views), got {args.target!r}")
        config = build_config({"plant": args.target, "seed": 0 if args.seed is None else args.seed})
        out = args.out or Path("traits.json")
    check_plant_name(registry, config)
    if out.exists() and not args.overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")
    plant = resolve_plant(registry, config)
    with EpisodeProgress("triangles") as progress:
        truth = plant_traits(plant, progress.update)
        measured = None
        if args.measure:
            measured = measure(target, args.depth, lambda done, total: progress.stage("views", done, total))
    doc = traits_document(plant, config.seed, truth, measured)
    write_json(out, doc)
    p = doc["plant"]
    print(
        f"{plant.name}: {p['leaf_count']} leaves, {p['leaf_area_m2'] * 1e4:.1f} cm^2 of leaf; "
        f"height {p['height_m'] * 100:.1f} cm, crown {p['crown_diameter_m'] * 100:.1f} cm, "
        f"hull {p['convex_hull_volume_m3'] * 1e3:.2f} L, projected {p['projected_area_m2'] * 1e4:.1f} cm^2; "
        f"mean leaf inclination {p['mean_inclination_deg']:.1f} deg ({p['de_wit_class']})"
    )
    found = {leaf.id: leaf for leaf in measured.leaves} if measured is not None else {}
    if measured is not None:
        e = doc["measured"]["errors"]
        print(
            f"measured from {measured.views} views ({measured.depth} depth): {e['leaves_seen']} of "
            f"{e['leaves_there']} leaves seen, {e['clusters']} clusters without instances "
            f"({e['clusters_one_leaf']} one leaf each); leaf area MAPE {e['area_mape_pct']:.1f}%, "
            f"inclination error {e['inclination_error_mean_deg']:.1f} deg; "
            f"height {measured.height_m * 100:.1f} cm ({e['height_error_m'] * 1e3:+.1f} mm), "
            f"hull {measured.convex_hull_volume_m3 * 1e3:.2f} L ({e['hull_volume_error_pct']:+.1f}%)"
        )
    leaves = doc["leaves"]
    extra = f"  {'measured':>8}  {'meas deg':>8}" if measured is not None else ""
    print(f"{'leaf':>5}  {'area cm^2':>9}  {'length cm':>9}  {'width cm':>8}  {'incl deg':>8}  {'azimuth':>7}{extra}")
    for leaf in leaves[:20]:
        seen = found.get(leaf["id"])
        cells = f"  {seen.area_m2 * 1e4:>8.2f}  {seen.inclination_deg:>8.1f}" if seen is not None else ""
        print(
            f"{leaf['id']:>5}  {leaf['area_m2'] * 1e4:>9.2f}  {leaf['length_m'] * 100:>9.2f}  "
            f"{leaf['width_m'] * 100:>8.2f}  {leaf['inclination_deg']:>8.1f}  {leaf['azimuth_deg']:>7.1f}{cells}"
        )
    if len(leaves) > 20:
        print(f"  ... {len(leaves) - 20} more in {out}")
    print(f"wrote {out}")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from agrisim.app.progress import EpisodeProgress
    from agrisim.files.exports import build_exporter, run_export
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
    from agrisim.app.progress import EpisodeProgress
    from agrisim.evaluation.photogrammetry import run_colmap

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


def _cmd_compare(args: argparse.Namespace) -> int:
    from agrisim.app.compare import SEG_MODES, compare, default_out, markdown_table, parse_names, plan_compare
    from agrisim.app.compare_plan import parse_sizes
    from agrisim.app.point_table import point_markdown
    from agrisim.app.progress import EpisodeProgress
    from agrisim.config import merge

    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be 1 or more, got {args.workers}")
    # Every `run` option at its default, then compare's episode options on top: the overrides
    # are built exactly as for `agrisim run`.
    episode = build_parser().parse_args(["run"])
    for flag, *_ in COMPARE_EPISODE_FLAGS:
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
        sys.stderr.write(
            f"{PROG}: {r['plant']} ({r.get('variant') or r['seg_mode']}) {r['status']}: {r.get('error', '')}\n"
        )
    if result.failed or result.missing:
        fail(
            f"{len(result.failed)} of {len(result.records)} episodes did not complete; "
            f"the table lacks {', '.join(result.missing) or 'nothing'}; --resume continues",
            status=1,
        )
    return 0


def _cmd_nextview(args: argparse.Namespace) -> int:
    from pathlib import Path

    from agrisim.app.nextview import (
        check_candidates,
        check_request,
        pivot,
        plot,
        prepare_out,
        read_episodes,
        run_benchmark,
        table,
    )
    from agrisim.app.progress import EpisodeProgress
    from agrisim.registry import Registry, make_plugin_manager

    out = Path(args.out)
    if args.report:
        if not (out / "nextview.json").is_file():
            raise UserError(f"{out} holds no benchmark (nextview.json) to report")
        episodes = read_episodes(out / "nextview.json")
        print(table(episodes) + "\n\n" + pivot(episodes))
        plot(episodes, out / "nextview.png")
        return 0

    # "all": the paper's ten species (the built-in species; Helios crops are named one by one)
    species = [name for name in Registry(make_plugin_manager()).specs("plant") if ":" not in name]
    plants = species if args.plant == ["all"] else list(args.plant)
    policies = [p.strip() for p in args.policies.split(",") if p.strip()]
    check_request(plants, policies, args.views)
    overrides: dict[str, Any] = {}
    apply_sets(overrides, args.set)
    options = {"resolution": args.resolution, "config": overrides}
    for plant in plants:  # a bad plant or setting, or views out of reach, before anything is written
        check_candidates(plant, options)
    prepare_out(out, args.overwrite)
    with EpisodeProgress("views") as progress:
        episodes = run_benchmark(plants, policies, args.views, out, options, args.seed, progress.stage)
    print(table(episodes) + "\n\n" + pivot(episodes))
    plot(episodes, out / "nextview.png")
    print(f"wrote {out / 'nextview.json'} and {out / 'nextview.png'}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from agrisim.app.progress import SweepProgress
    from agrisim.app.sweep import plan_sweep, read_spec
    from agrisim.app.sweep_run import sweep

    spec = read_spec(args.spec, args.set)
    # every cell validated and the folder checked before Ray starts or anything is written
    plan = plan_sweep(spec, out=args.out, overwrite=args.overwrite, resume=args.resume)
    kept = sum(c.action == "skip" for c in plan.cells)
    if kept:
        print(f"resuming: {kept} of {len(plan.cells)} runs complete already")
    with SweepProgress() as progress:
        result = sweep(
            plan,
            ray_address=args.ray_address,
            workers=args.workers,
            gpus=args.gpus,
            gpu_resource=args.gpu_resource,
            progress=progress.update,
        )
    for r in result.runs:
        line = f"  {r['name']}: {r['status']}, {r['views']} views"
        if r.get("seconds") is not None:
            line += f", {r['seconds']:.1f} s"
        print(line + (f" ({r['error']})" if r.get("error") else ""))
    print(f"{len(result.runs) - len(result.failed)} of {len(result.runs)} runs complete in {result.wall_s:.1f} s")
    print(f"output: {plan.out}  {plan.out / 'sweep.json'}")
    if result.failed:
        fail(f"{len(result.failed)} of {len(result.runs)} runs did not complete; --resume continues", status=1)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``agrisim`` console script."""
    args = build_parser().parse_args(argv)
    try:
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "plants":
            return _cmd_plants(args)
        if args.command == "traits":
            return _cmd_traits(args)
        if args.command == "nextview":
            return _cmd_nextview(args)
        if args.command == "recon":
            return _cmd_recon(args)
        if args.command == "export":
            return _cmd_export(args)
        if args.command == "render":
            return _cmd_render(args)
        if args.command == "compare":
            return _cmd_compare(args)
        if args.command == "sweep":
            return _cmd_sweep(args)
        if args.command == "colmap":
            return _cmd_colmap(args)
        if args.command == "view":
            return _cmd_view(args)
        if args.command == "ros":
            return _cmd_ros(args)
        if args.command == "doctor":
            return _cmd_doctor(args)
        return _cmd_plugins(args)
    except UserError as exc:
        fail(str(exc))
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted\n")
        return 130
    except BrokenPipeError:  # output piped into `head` and the like
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except BackendFailure as exc:  # a plugin's failure: named, the run's finished work kept
        fail(str(exc), status=1)
    except Exception as exc:  # an internal failure, not the user's input
        if os.environ.get("AGRISIM_DEBUG"):
            traceback.print_exc()
        fail(f"internal error: {type(exc).__name__}: {exc} (set AGRISIM_DEBUG=1 for the traceback)", status=1)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
