"""``agrisim frames RUN_DIR``: a run's views, arm by arm, with each camera's centre; a command
added by a plugin, as agrisim's own are (the ``agrisim_commands`` hook)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from agrisim.commands import Command
from agrisim.errors import UserError
from agrisim.files.rundir import read_json
from agrisim.registry import hookimpl


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run's output directory")
    parser.add_argument("--arm", metavar="NAME", help="only this arm's views")
    parser.add_argument("--json", action="store_true", help="the views as JSON")


def _frames(args: argparse.Namespace) -> int:
    frames = read_json(args.run_dir / "cameras.json", "not a run's directory")["frames"]
    views = {name: np.asarray(f["world_T_camera"], float)[:3, 3] for name, f in sorted(frames.items())}
    arms = sorted({name.split("_")[0] for name in views})
    if args.arm is not None and args.arm not in arms:
        raise UserError(f"--arm {args.arm!r}: the run's arms are {', '.join(arms)}")
    views = {n: c for n, c in views.items() if args.arm is None or n.startswith(f"{args.arm}_")}
    if args.json:
        print(json.dumps({n: [round(float(x), 6) for x in c] for n, c in views.items()}))
        return 0
    for arm in [args.arm] if args.arm else arms:
        mine = [n for n in views if n.startswith(f"{arm}_")]
        print(f"{arm}: {len(mine)} views")
        for n in mine:
            print(f"  {n}  centre {views[n][0]:+.4f} {views[n][1]:+.4f} {views[n][2]:+.4f} m")
    return 0


@hookimpl
def agrisim_commands() -> list[Command]:
    return [
        Command(
            "frames",
            help="a run's views, arm by arm, with each camera's centre",
            description="List the views of a run directory, arm by arm, with each camera's centre in the world.",
            add_arguments=_arguments,
            run=_frames,
        )
    ]
