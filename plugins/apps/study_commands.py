"""The commands that run many episodes: ``nextview``, ``compare`` (the paper's Tables 2 and 3)
and ``sweep``. Each is a :class:`~agrisim.commands.Command`, its flags and the function of its
parsed flags, registered by :mod:`agrisim.plugins.apps.commands`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from agrisim.app.arguments import PROG, Parser, fail
from agrisim.commands import Command
from agrisim.config import load_toml
from agrisim.errors import UserError
from agrisim.plugins.apps import run_commands
from agrisim.plugins.apps.flags import (
    COMPARE_EPISODE_FLAGS,
    apply_sets,
    overrides_from_args,
    set_flag,
)


def _nextview_arguments(nextview: argparse.ArgumentParser) -> None:
    nextview.add_argument(
        "--plant", nargs="+", default=["coltsfoot"], metavar="NAME", help="species or plant files, or 'all' (coltsfoot)"
    )
    from agrisim.plugins.apps.nextview.policies import POLICIES

    nextview.add_argument(
        "--policies", default=",".join(POLICIES), help=f"comma-separated: {', '.join(POLICIES)} (all)"
    )
    nextview.add_argument(
        "--views", type=int, metavar="N", help="views each policy but paper takes: the one budget N (see --budgets)"
    )
    nextview.add_argument(
        "--budgets",
        metavar="N,N,...",
        help="the views to report coverage at, comma-separated; each policy but paper takes the largest (5,10,20,30); "
        "with --report, the views to report the benchmark in --out at",
    )
    nextview.add_argument("--resolution", default="480x270", metavar="WxH", help="the camera's images (480x270)")
    nextview.add_argument("--seed", type=int, metavar="S", help="the one seed S: the plant's, the episode's (0)")
    nextview.add_argument(
        "--seeds",
        type=int,
        metavar="N",
        help="N seeds, 0 to N-1, each the plant's and the episode's: the mean and 95%% interval over them, "
        "each policy paired against random",
    )
    nextview.add_argument("--out", type=Path, default=Path("nextview"), help="output directory (./nextview)")
    nextview.add_argument("--overwrite", action="store_true", help="replace a benchmark already in --out")
    nextview.add_argument(
        "--report", action="store_true", help="print the table and draw the plot of the benchmark in --out again"
    )
    set_flag(nextview, "any setting of the episodes by its dotted name, e.g. physics.backend=kinematic")


def _compare_arguments(compare: argparse.ArgumentParser) -> None:
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
    for flag, meta, kind, text in COMPARE_EPISODE_FLAGS:
        compare.add_argument(flag, metavar=meta, type=kind, help=text)
    set_flag(compare, "any setting by its dotted name")


def _sweep_arguments(sweep: argparse.ArgumentParser) -> None:
    sweep.add_argument("spec", type=Path, metavar="SPEC", help="the sweep's TOML file")
    sweep.add_argument(
        "--out", type=Path, required=True, metavar="DIR", help="the sweep's folder: a run folder per cell"
    )
    sweep.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    sweep.add_argument(
        "--resume", action="store_true", help="continue the sweep in --out: complete runs kept, unfinished resumed"
    )
    sweep.add_argument(
        "--ray-address", metavar="ADDR", help="join this Ray cluster (HOST:PORT or auto; default: a local Ray)"
    )
    sweep.add_argument("--workers", type=int, metavar="N", help="CPU runs at a time (default: one per core)")
    sweep.add_argument("--gpus", type=int, metavar="N", help="GPU runs at a time, one per GPU (default: every GPU)")
    sweep.add_argument(
        "--gpu-resource",
        default="GPU",
        metavar="NAME",
        help="the Ray resource a GPU run takes one of (default: GPU; a custom resource a cluster declares)",
    )
    set_flag(sweep, "any setting of the base configuration by its dotted name")


def _cmd_compare(args: argparse.Namespace) -> int:
    from agrisim.config import merge
    from agrisim.plugins.apps.compare import SEG_MODES, compare, default_out, markdown_table, parse_names, plan_compare
    from agrisim.plugins.apps.compare_plan import parse_sizes
    from agrisim.plugins.apps.point_table import point_markdown
    from agrisim.plugins.apps.progress import EpisodeProgress

    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be 1 or more, got {args.workers}")
    # Every `run` option at its default, then compare's episode options on top: the overrides
    # are built exactly as for `agrisim run`.
    run = next(c for c in run_commands.COMMANDS if c.name == "run")
    parser = Parser(prog=f"{PROG} run")
    run.add_arguments(parser)
    episode = parser.parse_args([])
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

    from agrisim.plugins.apps.nextview.study import (
        check_candidates,
        check_request,
        plot,
        prepare_out,
        read_benchmark,
        report,
        resolve_budgets,
        resolve_seeds,
        run_benchmark,
    )
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.registry import Registry, make_plugin_manager

    out = Path(args.out)
    if args.report:
        if not (out / "nextview.json").is_file():
            raise UserError(f"{out} holds no benchmark (nextview.json) to report")
        episodes, budgets = read_benchmark(out / "nextview.json")
        if args.budgets is not None or args.views is not None:
            budgets = resolve_budgets(args.views, args.budgets)
        print(report(episodes, budgets))
        plot(episodes, out / "nextview.png", budgets)
        return 0

    budgets = resolve_budgets(args.views, args.budgets)
    seeds = resolve_seeds(args.seed, args.seeds)
    # "all": the paper's ten species (the built-in species; Helios crops are named one by one)
    species = [name for name in Registry(make_plugin_manager()).specs("plant") if ":" not in name]
    plants = species if args.plant == ["all"] else list(args.plant)
    policies = [p.strip() for p in args.policies.split(",") if p.strip()]
    check_request(plants, policies, max(budgets))
    overrides: dict[str, Any] = {}
    apply_sets(overrides, args.set)
    options = {"resolution": args.resolution, "config": overrides}
    for plant in plants:  # a bad plant or setting, or views out of reach, before anything is written
        check_candidates(plant, options)
    prepare_out(out, args.overwrite)
    with EpisodeProgress("views") as progress:
        episodes = run_benchmark(
            plants, policies, max(budgets), out, options, progress=progress.stage, seeds=seeds, budgets=budgets
        )
    print(report(episodes, budgets))
    plot(episodes, out / "nextview.png", budgets)
    print(f"wrote {out / 'nextview.json'} and {out / 'nextview.png'}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from agrisim.plugins.apps.progress import SweepProgress
    from agrisim.plugins.apps.sweep import plan_sweep, read_spec
    from agrisim.plugins.apps.sweep_run import sweep

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


#: this module's commands, each its flags and its function
COMMANDS = [
    Command(
        "nextview",
        help="which views to take: policies compared on agrisim/PlantView-v0 (coverage against views and motion)",
        description="Run each policy's episode on each plant in agrisim/PlantView-v0 (the paper's 100 views first: "
        "the coverage the others must reach), and write OUT/nextview.json (coverage and motion after every view), "
        "OUT/nextview.png and a run directory per episode; print the table. --seeds N runs every episode on N "
        "seeds and reports each policy's mean coverage at each of --budgets with a 95% interval, paired against "
        "random, the share of the oracle's gap it closes and its time deciding beside the arms' motion.",
        add_arguments=_nextview_arguments,
        run=_cmd_nextview,
    ),
    Command(
        "compare",
        help="the paper's Table 2: every plant in both segmentation modes, episodes on Ray",
        description="Run every plant in both segmentation modes (texture, repopa) as Ray tasks, each into "
        "OUT/<plant>/<seg_mode>, and write the paper's Table 2 with accuracy: OUT/table.md, table.csv, chart.png.",
        add_arguments=_compare_arguments,
        run=_cmd_compare,
    ),
    Command(
        "sweep",
        help="a grid of runs from one TOML spec ([axes]: settings and their values), runs on Ray",
        description="Run every cell of the grid that SPEC's [axes] table spans (dotted settings, as --set takes "
        "them, each with a list of values; the rest of SPEC is the base configuration, as --config reads one) as a "
        "Ray task, each into its own run folder OUT/<axis values>, with [sweep] after = [colmap, coco, nerfstudio] "
        "on each complete run; OUT/sweep.json lists every run, its settings, status and figures.",
        add_arguments=_sweep_arguments,
        run=_cmd_sweep,
    ),
]
