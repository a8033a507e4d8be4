"""The ``agrisim`` command line: ``agrisim run``, ``agrisim plants`` and ``agrisim plugins``.

Bad input exits with status 2 and one line naming the problem; nothing is written. Internal
failures exit 1 (``AGRISIM_DEBUG=1`` shows the traceback) with the run's partial results kept.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from agrisim.config import RunConfig, build_config, load_toml
from agrisim.errors import UserError

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


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description="Robot arms photographing plants: simulate, annotate, reconstruct.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    run = sub.add_parser("run", help="run one episode of the routine", description="Run one episode of the routine.")
    run.add_argument("--config", type=Path, metavar="TOML", help="configuration file; flags override it")
    run.add_argument("--plant", metavar="NAME|PATH", help="species (agrisim plants) or a .glb/.gltf/.obj file")
    run.add_argument("--seg-mode", choices=["texture", "repopa"], help="segmentation mode (default: texture)")
    run.add_argument("--labels", choices=["plant", "organs"], help="one plant label, or one per organ (default: plant)")
    run.add_argument("--renderer", metavar="NAME", help="renderer (default: raycast; none: robots only)")
    run.add_argument("--shadow-samples", type=int, metavar="N", help="shadow rays per pixel, 0..32 (default: 1)")
    run.add_argument("--supersample", type=int, metavar="S", help="S x S RGB rays per pixel, 1..4 (default: 1)")
    run.add_argument("--hide-robots", action="store_true", default=None, help="render without the arms")
    run.add_argument("--pcg-seed", type=int, metavar="N", help="seed of the lab clutter (default: 42)")
    run.add_argument("--physics", metavar="NAME", help="physics backend (default: pybullet)")
    run.add_argument("--planner", metavar="NAME", help="motion planner (default: ompl)")
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
    return p


def _set(tree: dict[str, Any], dotted: str, value: Any) -> None:
    keys = dotted.split(".")
    node = tree
    for key in keys[:-1]:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise UserError(f"--set {dotted}: {key!r} is not a table")
    node[keys[-1]] = value


def _parse_value(text: str) -> Any:
    """A TOML value (number, bool, string, array); bare words are strings."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def overrides_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """The flags given on the command line, as a nested config dictionary."""
    out: dict[str, Any] = {}
    flat = {
        "plant": args.plant,
        "render.seg_mode": args.seg_mode,
        "render.labels": args.labels,
        "renderer.backend": args.renderer,
        "render.shadow_samples": args.shadow_samples,
        "render.supersample": args.supersample,
        "render.hide_robots": args.hide_robots,
        "pcg_seed": args.pcg_seed,
        "physics.backend": args.physics,
        "planner.backend": args.planner,
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
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set expects KEY=VALUE, got {item!r}")
        _set(out, key.strip(), _parse_value(value.strip()))
    return out


def _cmd_run(args: argparse.Namespace) -> int:
    from agrisim.episode import Episode
    from agrisim.progress import EpisodeProgress

    overrides = overrides_from_args(args)
    if args.resume:
        config = _resume_config(args, overrides)
    else:
        base = load_toml(args.config) if args.config else {}
        config = build_config(base, overrides)
    episode = Episode(config)  # validates everything; nothing is written before run()
    with EpisodeProgress() as progress:
        run, summary = episode.run(progress=progress.update)
    rrd = None
    if not config.output.no_rrd:
        rrd = config.output.rrd or run.out_dir / "recording.rrd"
    print(f"reached {summary.reached}/{summary.setpoints} setpoints, {summary.collisions} with collisions")
    worst = max((r.ee_error_mm for r in run.results if r.reached and r.ee_error_mm is not None), default=None)
    if worst is not None:
        print(f"worst camera error at a reached setpoint: {worst:.4f} mm")
    for r in run.results:
        if not r.reached:
            print(f"  {r.frame}: {r.reason}")
    stages = ", ".join(f"{k} {v:.1f} s" for k, v in summary.wall_s.items())
    print(f"simulated {summary.sim_time:.1f} s; wall time: {stages}")
    print(f"output: {run.out_dir}" + (f"  recording: {rrd}" if rrd else ""))
    return 0


def _resume_config(args: argparse.Namespace, overrides: dict[str, Any]) -> RunConfig:
    """The saved configuration of the run in --out, with only output flags applied."""
    from agrisim.episode import saved_run

    if args.overwrite:
        raise UserError("--overwrite and --resume exclude each other")
    if args.out is None:
        raise UserError("--resume needs --out DIR: the run to continue")
    if args.config is not None or set(overrides) - {"output"}:
        raise UserError("--resume continues the run's saved configuration: give only --out and output options")
    saved = saved_run(args.out)["config"]
    return build_config(saved, {"output": {**overrides["output"], "overwrite": False}})


def _cmd_plugins(args: argparse.Namespace) -> int:
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
            if args.options:
                for field, info in spec.options_model.model_fields.items():
                    doc = (info.description or "").replace("\n", " ")
                    print(f"  {'':<{width}}    {kind}.{name}.{field} = {info.default!r}  {doc}")
    return 0


def _cmd_plants(args: argparse.Namespace) -> int:
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.texturing import cutaway_fraction

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
        plant = spec.factory(spec.options_model()).build(args.seed)
        organs = ", ".join(lab.name for lab in plant.labels.labels if lab.id)
        cut = cutaway_fraction(plant.mesh, samples=100_000)
        print(f"{name:<{width}}  {len(plant.mesh.faces):>9,}  {cut:>7.1%}  {organs}  [{spec.distribution}]")
    print("cut away: share of the plant's surface area that opacity removes (what RepOpa labels wrongly)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``agrisim`` console script."""
    args = _parser().parse_args(argv)
    try:
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "plants":
            return _cmd_plants(args)
        return _cmd_plugins(args)
    except UserError as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        sys.stderr.write(f"{PROG}: interrupted\n")
        return 130
    except BrokenPipeError:  # output piped into `head` and the like
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception as exc:  # an internal failure, not the user's input
        if os.environ.get("AGRISIM_DEBUG"):
            traceback.print_exc()
        _fail(f"internal error: {type(exc).__name__}: {exc} (set AGRISIM_DEBUG=1 for the traceback)", status=1)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
