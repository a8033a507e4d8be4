"""The ``agrisim`` command line's grammar: every subcommand's flags, and the nested config
dictionary the run flags and ``--set KEY=VALUE`` make (what :mod:`agrisim.app.cli` runs).

Bad flags exit with status 2 and one line (no usage dump).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from agrisim.errors import UserError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PROG = "agrisim"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump), exit status 2."""

    def error(self, message: str) -> NoReturn:
        fail(message)


def fail(message: str, status: int = 2) -> NoReturn:
    """Exit with ``status`` after one line on stderr: ``agrisim: error: <message>``."""
    sys.stderr.write(f"{PROG}: error: {message}\n")
    raise SystemExit(status)


# Long but flat: one declaration per flag, the CLI's reference in one place.
def build_parser() -> argparse.ArgumentParser:
    """The parser of every subcommand."""
    from agrisim.version import __version__

    p = _Parser(prog=PROG, description="Robot arms photographing plants: simulate, annotate, reconstruct.")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    run = sub.add_parser("run", help="run one episode of the routine", description="Run one episode of the routine.")
    _episode_flags(run)
    run.add_argument(
        "--serve-web",
        action="store_true",
        help="stream the run live to Rerun's web viewer, served here (print its address; after the run, serve until Ctrl-C)",
    )
    _web_flags(run)
    run.add_argument(
        "--resume",
        action="store_true",
        default=None,
        help="continue the unfinished run in --out with its saved configuration",
    )
    _set_flag(run, "any setting by its dotted name, e.g. physics.pybullet.position_gain=0.5")

    ros = sub.add_parser(
        "ros",
        help="serve the cell live over ROS 1 or ROS 2: trajectories in, views on a trigger, topics out",
        description="Serve a live session of the cell (loaded as agrisim run loads it) over ROS: joint "
        "trajectories in, views on a trigger, joint states, TF and images out; every view saved to --out.",
    )
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
    _episode_flags(ros)
    ros.set_defaults(resume=None)
    _set_flag(ros, "any setting by its dotted name, e.g. physics.pybullet.position_gain=0.5")

    plants = sub.add_parser("plants", help="list the plant species: triangles, organs, area cut away by opacity")
    plants.add_argument("--seed", type=int, default=0, metavar="N", help="seed to grow each species with (0)")
    traits = sub.add_parser(
        "traits",
        help="a plant's traits, exact from its model: leaf by leaf, and the whole plant's",
        description="Measure a plant's traits exactly from its model: each leaf's area (its opaque texels), midrib "
        "length, width, inclination, azimuth, attachment and centroid; the plant's leaf count and area, height, crown "
        "diameter, convex-hull volume, projected area and leaf angle distribution (nearest de Wit class). Prints "
        "them and writes traits.json (RUN/traits.json for a run); with --measure, a run's traits are also measured "
        "from its views and scored against the truth. Definitions and units: docs/traits.md.",
    )
    traits.add_argument(
        "target",
        metavar="PLANT|RUN",
        help="a species (agrisim plants), a plant file (glTF/GLB/OBJ whose leaves are instances), or a run's directory",
    )
    traits.add_argument(
        "--seed", type=int, default=None, metavar="N", help="seed to grow a species with (0; a run's own for a run)"
    )
    traits.add_argument(
        "--out", type=Path, default=None, help="traits.json's path (default: RUN/traits.json, or ./traits.json)"
    )
    traits.add_argument("--overwrite", action="store_true", help="replace an existing traits.json")
    traits.add_argument(
        "--measure",
        action="store_true",
        help="also measure the traits from the run's views, as a phenotyping pipeline would, and score them "
        'against the truth (traits.json\'s "measured")',
    )
    traits.add_argument(
        "--depth",
        choices=["sensor", "truth"],
        default="sensor",
        help="with --measure: the run's depth sensor (its exact depth where it had none; default) or the exact depth",
    )
    nextview = sub.add_parser(
        "nextview",
        help="which views to take: policies compared on agrisim/PlantView-v0 (coverage against views and motion)",
        description="Run each policy's episode on each plant in agrisim/PlantView-v0 (the paper's 100 views first: "
        "the coverage the others must reach), and write OUT/nextview.json (coverage and motion after every view), "
        "OUT/nextview.png and a run directory per episode; print the table.",
    )
    nextview.add_argument(
        "--plant", nargs="+", default=["coltsfoot"], metavar="NAME", help="species or plant files, or 'all' (coltsfoot)"
    )
    from agrisim.nextview.policies import POLICIES

    nextview.add_argument(
        "--policies", default=",".join(POLICIES), help=f"comma-separated: {', '.join(POLICIES)} (all)"
    )
    nextview.add_argument("--views", type=int, default=30, metavar="N", help="views each policy but paper takes (30)")
    nextview.add_argument("--resolution", default="480x270", metavar="WxH", help="the camera's images (480x270)")
    nextview.add_argument("--seed", type=int, default=0, metavar="N", help="plant and policy seed (0)")
    nextview.add_argument("--out", type=Path, default=Path("nextview"), help="output directory (./nextview)")
    nextview.add_argument("--overwrite", action="store_true", help="replace a benchmark already in --out")
    nextview.add_argument(
        "--report", action="store_true", help="print the table and draw the plot of the benchmark in --out again"
    )
    _set_flag(nextview, "any setting of the episodes by its dotted name, e.g. physics.backend=kinematic")
    plugins = sub.add_parser("plugins", help="list every backend of every kind and where it comes from")
    plugins.add_argument("--options", action="store_true", help="also list each backend's options")
    doctor = sub.add_parser(
        "doctor",
        help="what this machine can run: CPU, libLLVM, GPUs, ROS, every backend, speed against the README's",
        description="Report what this machine can run: Python, the CPU's vector instructions, the libLLVM Dr.Jit "
        "loaded, CUDA for Mitsuba and PyTorch, ROS 1, Cyclone DDS, the tests' browser, every backend (and why "
        "not), and one 1080p raycast view and the IK timed against the README's figures. Exit status 1 when "
        "agrisim run with its defaults cannot work here.",
    )
    doctor.add_argument("--json", action="store_true", help="write the same facts as JSON to stdout")
    doctor.add_argument("--no-timing", action="store_true", help="skip the two timings (a few seconds)")
    recon = sub.add_parser(
        "recon",
        help="rebuild a run's reconstruction and metrics from its files",
        description="Rebuild the reconstruction (clouds/) and metrics.json of a complete run from its images.",
    )
    recon.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a complete run's output directory")
    recon.add_argument("--recon", metavar="NAME", help="reconstructor (default: the run's own)")
    recon.add_argument("--out", type=Path, metavar="DIR", help="write clouds/ and metrics.json here (default: RUN_DIR)")
    recon.add_argument("--overwrite", action="store_true", help="replace existing clouds and metrics.json")
    _set_flag(recon, "recon.* or metrics.* settings, e.g. recon.tsdf.voxel_size=0.003")
    render = sub.add_parser(
        "render",
        help="re-render a finished run's RGB with another renderer (e.g. path-traced), keeping its labels and depth",
        description="Draw the RGB of a complete run again from its saved scene, camera and arm poses, into a complete "
        "dataset (default: RUN_DIR-<renderer>); labels, depth, instances, clouds and metrics are carried over.",
    )
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
    _set_flag(render, "renderer.* settings, e.g. renderer.mitsuba.spp=64")
    export = sub.add_parser(
        "export",
        help="export a run directory to another tool's format (an exporter: agrisim plugins lists them)",
        description="Export a run directory with an exporter (agrisim plugins lists the installed ones, with "
        "their options): nerfstudio writes RUN_DIR/transforms.json and RUN_DIR/masks/; "
        "coco writes RUN_DIR/coco/annotations.json (COCO instance masks); rosbag writes RUN_DIR/rosbag/ "
        "(a ROS 2 bag in MCAP: TF, joint states, planned trajectories, camera images, depth, labels, clouds). "
        "OUT puts the export elsewhere (coco: the JSON file; rosbag: the bag's folder; nerfstudio takes none).",
    )
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
    _set_flag(export, "an option of the exporter by its dotted name, exporter.NAME.KEY=VALUE")
    colmap = sub.add_parser(
        "colmap",
        help="COLMAP's structure from motion on a run's views, scored against the true cameras",
        description="Recover the cameras of a complete run's RGB views with COLMAP (pycolmap, CPU): SIFT features, "
        "matching, incremental mapping; align the model to the true camera centres by a similarity and score each "
        "view (centre error, rotation error, reprojection error). Writes RUN_DIR/colmap/ (sparse/0/, poses.json).",
    )
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
    for flag, meta, kind, text in COMPARE_EPISODE_FLAGS:
        compare.add_argument(flag, metavar=meta, type=kind, help=text)
    _set_flag(compare, "any setting by its dotted name")
    _sweep_flags(sub)
    return p


def _sweep_flags(sub: Any) -> None:
    """``agrisim sweep SPEC``: a grid of runs on Ray (:mod:`agrisim.app.sweep`)."""
    sweep = sub.add_parser(
        "sweep",
        help="a grid of runs from one TOML spec ([axes]: settings and their values), runs on Ray",
        description="Run every cell of the grid that SPEC's [axes] table spans (dotted settings, as --set takes "
        "them, each with a list of values; the rest of SPEC is the base configuration, as --config reads one) as a "
        "Ray task, each into its own run folder OUT/<axis values>, with [sweep] after = [colmap, coco, nerfstudio] "
        "on each complete run; OUT/sweep.json lists every run, its settings, status and figures.",
    )
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
    _set_flag(sweep, "any setting of the base configuration by its dotted name")


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


def _episode_flags(parser: argparse.ArgumentParser) -> None:
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


def _set_flag(parser: argparse.ArgumentParser, text: str) -> None:
    """``--set KEY=VALUE``, repeatable: settings by their dotted names (``text`` says which)."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help=text)


def _web_flags(parser: argparse.ArgumentParser) -> None:
    from agrisim.app.web import DEFAULT_BIND, DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT

    parser.add_argument("--web-port", type=int, metavar="N", help=f"port of the web page (default: {DEFAULT_WEB_PORT})")
    parser.add_argument(
        "--grpc-port",
        type=int,
        metavar="N",
        help=f"port the page reads the recording from (default: {DEFAULT_GRPC_PORT})",
    )
    parser.add_argument(
        "--bind",
        metavar="ADDR",
        help=f"address to serve on (default: {DEFAULT_BIND}, this machine only; 0.0.0.0: every interface)",
    )


def web_address(args: argparse.Namespace) -> tuple[str, int, int]:
    """(bind, web port, gRPC port) of ``--bind``, ``--web-port``, ``--grpc-port``, checked."""
    from agrisim.app.web import DEFAULT_BIND, DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT, check_address

    bind = args.bind or DEFAULT_BIND
    web = args.web_port if args.web_port is not None else DEFAULT_WEB_PORT
    grpc = args.grpc_port if args.grpc_port is not None else DEFAULT_GRPC_PORT
    if web == grpc:
        raise UserError(f"--web-port and --grpc-port must differ (both {web})")
    check_address(bind, {"--web-port": web, "--grpc-port": grpc})
    return bind, web, grpc


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
    for key, value in flat.items():
        if value is not None:
            set_dotted(out, key, value)
    apply_sets(out, args.set)
    return out


def apply_sets(tree: dict[str, Any], items: Sequence[str]) -> None:
    """``--set KEY=VALUE`` items into a nested config dictionary."""
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set expects KEY=VALUE, got {item!r}")
        set_dotted(tree, key.strip(), parse_value(value.strip()))
