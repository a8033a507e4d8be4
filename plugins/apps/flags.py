"""The flags several of agrisim's commands share (the episode's, ``--set``) and the nested
config dictionary they make."""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agrisim.errors import UserError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: the rig that --robot, --robot-urdf and --camera-link choose
SINGLE_ARM = "single-arm"

#: the episode options `compare` passes on (as `agrisim run` has them)
COMPARE_EPISODE_FLAGS: list[tuple[str, str, Any, str]] = [
    ("--labels", "plant|organs", str, "one plant label, or one per organ (default: plant)"),
    ("--plant-age", "DAYS", float, "age of every growing plant (helios:*), days (default: each model's)"),
    ("--plant-seed", "N", int, "the individual every species grows (default: --seed)"),
    ("--renderer", "NAME", str, "renderer (default: raycast)"),
    ("--shadow-samples", "N", int, "shadow rays per pixel, 0..32 (default: 1)"),
    ("--depth-sensor", "NAME", str, "depth camera for depth_sensor/ and the reconstruction (default: exact)"),
    ("--imager", "NAME", str, "the colour camera's sensor and processing (default: none, noise-free)"),
    ("--physics", "NAME", str, "physics backend (default: pybullet)"),
    ("--planner", "NAME", str, "motion planner (default: ompl)"),
    ("--recon", "NAME", str, "reconstructor (default: pointcloud)"),
    ("--camera", "PRESET", str, "camera preset (default: rpi3-wide-1080p)"),
    ("--camera-calibration", "FILE", Path, "the camera from OpenCV's YAML/JSON or ROS camera_info (not a preset)"),
    ("--resolution", "WxH", str, "image size (default: the preset's 1920x1080)"),
    ("--setpoints", "LxC", str, "L levels x C columns per arm (default: 5x10)"),
    ("--seed", "N", int, "seed for IK restarts and planners (default: 0)"),
    ("--pcg-seed", "N", int, "seed of the lab clutter (default: 42)"),
]


def episode_flags(parser: argparse.ArgumentParser) -> None:
    """The flags that load the cell, the plant and the backends (``run`` and ``ros``)."""
    run = parser
    run.add_argument("--config", type=Path, metavar="TOML", help="configuration file; flags override it")
    run.add_argument(
        "--plant",
        metavar="NAME|PATH",
        help="species (agrisim plants), a .glb/.gltf/.obj mesh or a .ply/.pcd point cloud",
    )
    run.add_argument("--plant-age", type=float, metavar="DAYS", help="age of a growing plant (helios:*), days")
    run.add_argument(
        "--plant-seed", type=int, metavar="N", help="grow another individual of the species (default: --seed)"
    )
    run.add_argument(
        "--bench", metavar="RxC", help="a bench of R rows by C columns of plants instead of one (e.g. 2x3)"
    )
    run.add_argument("--spacing", type=float, metavar="M", help="the bench's pot spacing, metres (default: 0.5)")
    run.add_argument(
        "--as-points",
        type=int,
        metavar="N",
        help="draw the plant as N points sampled on its opaque surface (the paper's Table 3)",
    )
    run.add_argument(
        "--point-size",
        type=float,
        metavar="M",
        help="diameter of each point of a point plant, metres (default: one that covers its surface)",
    )
    run.add_argument("--seg-mode", choices=["texture", "repopa"], help="segmentation mode (default: texture)")
    run.add_argument("--labels", choices=["plant", "organs"], help="one plant label, or one per organ (default: plant)")
    run.add_argument("--renderer", metavar="NAME", help="renderer (default: raycast; none: robots only)")
    run.add_argument("--shadow-samples", type=int, metavar="N", help="shadow rays per pixel, 0..32 (default: 1)")
    run.add_argument(
        "--depth-sensor",
        metavar="NAME",
        help="the depth camera whose measurement goes to depth_sensor/ and to the reconstruction "
        "(default: exact; azure-kinect-nfov, d435, d415, d405; see agrisim plugins)",
    )
    run.add_argument(
        "--imager",
        metavar="NAME",
        help="the colour camera's sensor and processing: noise, Bayer mosaic, exposure, vignetting "
        "(default: none, noise-free; imx708, ov2740)",
    )
    run.add_argument(
        "--exposure", metavar="auto|SECONDS", help="the imager's exposure time, or auto-exposure (default: auto)"
    )
    run.add_argument(
        "--jpeg-quality",
        type=int,
        metavar="Q",
        help="the imager's images through JPEG at quality 1..100 (default: off)",
    )
    run.add_argument("--supersample", type=int, metavar="S", help="S x S RGB rays per pixel, 1..4 (default: 1)")
    run.add_argument("--hide-robots", action="store_true", default=None, help="render without the arms")
    run.add_argument(
        "--depth-format",
        choices=["png16", "exr", "both"],
        help="depth as uint16 mm PNG, float32 m EXR, or both (default: png16)",
    )
    run.add_argument("--pcg-seed", type=int, metavar="N", help="seed of the lab clutter (default: 42)")
    run.add_argument(
        "--rig", metavar="NAME", help="what moves the cameras around the plant (default: paper, the two UR10s)"
    )
    run.add_argument(
        "--robot",
        metavar="NAME",
        help="one arm of example-robot-data's beside the plant (the single-arm rig): ur3, ur5, ur10, panda, "
        "xarm7, kinova, z1",
    )
    run.add_argument("--robot-urdf", type=Path, metavar="FILE", help="one arm from your URDF (the single-arm rig)")
    run.add_argument("--camera-link", metavar="LINK", help="the link of --robot-urdf the camera mounts on")
    run.add_argument("--physics", metavar="NAME", help="physics backend (default: pybullet)")
    run.add_argument("--planner", metavar="NAME", help="motion planner (default: ompl)")
    run.add_argument("--recon", metavar="NAME", help="reconstructor (default: pointcloud; none: no reconstruction)")
    run.add_argument("--camera", metavar="PRESET", help="camera preset (default: rpi3-wide-1080p)")
    run.add_argument(
        "--camera-calibration",
        type=Path,
        metavar="FILE",
        help="the camera from a calibration: OpenCV's YAML/JSON or ROS's camera_info YAML (size, K, lens)",
    )
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


def set_dotted(tree: dict[str, Any], dotted: str, value: Any) -> None:
    """``tree["a"]["b"] = value`` for ``dotted`` = ``"a.b"``, making the tables on the way."""
    keys = dotted.split(".")
    node = tree
    for key in keys[:-1]:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise UserError(f"--set {dotted}: {key!r} is not a table")
    node[keys[-1]] = value


def parse_value(text: str) -> Any:
    """A TOML value (number, bool, string, array); bare words are strings, and so are words
    like ``0x1`` that TOML would read as hexadecimal, octal or binary numbers (a grid ``LxC``)."""
    if re.fullmatch(r"[+-]?0[xob][0-9a-fA-F_]*", text.strip()):
        return text
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def set_flag(parser: argparse.ArgumentParser, text: str) -> None:
    """``--set KEY=VALUE``, repeatable: settings by their dotted names (``text`` says which)."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help=text)


def _exposure(text: str | None) -> str | float | None:
    """``--exposure``: ``auto`` or seconds."""
    if text is None or text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        raise UserError(f"--exposure {text!r}: give auto or a time in seconds (e.g. 0.01)") from None


def overrides_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """The flags given on the command line, as a nested config dictionary."""
    out: dict[str, Any] = {}
    flat = {
        "plant": args.plant,
        "plant_age": args.plant_age,
        "plant_seed": args.plant_seed,
        "bench.grid": args.bench,
        "bench.spacing": args.spacing,
        "points.count": args.as_points,
        "points.size": args.point_size,
        "render.seg_mode": args.seg_mode,
        "render.labels": args.labels,
        "renderer.backend": args.renderer,
        "sensor.backend": getattr(args, "depth_sensor", None),
        "imager.model": getattr(args, "imager", None),
        "imager.exposure": _exposure(getattr(args, "exposure", None)),
        "imager.jpeg_quality": getattr(args, "jpeg_quality", None),
        "render.shadow_samples": args.shadow_samples,
        "render.supersample": args.supersample,
        "render.hide_robots": args.hide_robots,
        "render.depth_format": args.depth_format,
        "pcg_seed": args.pcg_seed,
        "rig.backend": getattr(args, "rig", None),
        "physics.backend": args.physics,
        "planner.backend": args.planner,
        "recon.backend": args.recon,
        "camera.preset": args.camera,
        "camera.calibration": str(args.camera_calibration) if args.camera_calibration else None,
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
    flat.update(_single_arm(args))
    for key, value in flat.items():
        if value is not None:
            set_dotted(out, key, value)
    apply_sets(out, args.set)
    return out


def _single_arm(args: argparse.Namespace) -> dict[str, Any]:
    """``--robot``, ``--robot-urdf`` and ``--camera-link``: the single-arm rig's options, which
    choose that rig (another rig named by ``--rig`` is refused)."""
    robot, urdf, link = (getattr(args, name, None) for name in ("robot", "robot_urdf", "camera_link"))
    if robot is None and urdf is None and link is None:
        return {}
    given = "--robot" if robot is not None else "--robot-urdf" if urdf is not None else "--camera-link"
    rig = getattr(args, "rig", None)
    if rig not in (None, SINGLE_ARM):
        raise UserError(f"{given} chooses the {SINGLE_ARM} rig, not --rig {rig}")
    if link is not None and urdf is None:
        raise UserError("--camera-link goes with --robot-urdf FILE (the link of that URDF the camera mounts on)")
    if urdf is not None and link is None:
        raise UserError("--robot-urdf needs --camera-link LINK, the link of the URDF the camera mounts on")
    if robot is not None and urdf is not None:
        raise UserError("give --robot NAME or --robot-urdf FILE, not both")
    return {
        "rig.backend": SINGLE_ARM,
        f"rig.{SINGLE_ARM}.robot": robot,
        f"rig.{SINGLE_ARM}.urdf": str(urdf) if urdf is not None else None,
        f"rig.{SINGLE_ARM}.camera_link": link,
    }


def apply_sets(tree: dict[str, Any], items: Sequence[str]) -> None:
    """``--set KEY=VALUE`` items into a nested config dictionary."""
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set expects KEY=VALUE, got {item!r}")
        set_dotted(tree, key.strip(), parse_value(value.strip()))
