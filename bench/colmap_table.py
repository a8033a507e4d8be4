"""The paper's photogrammetry test, with numbers: for each plant, a run of the routine's views
(``agrisim run``), then ``agrisim colmap`` on them; one markdown row a plant: views registered,
camera centre and rotation errors against the truth, reprojection error, COLMAP's seconds.
Prints the CPU model first; asserts nothing. Each run goes to OUT/<plant>[-arms]/.

    python bench/colmap_table.py OUT [--plants coltsfoot boston_fern ...] [--resolution 960x540]
        [--shadow-samples 8] [--arms] [--matcher exhaustive] [--colmap-flags '--priors none'] [--rerender]
        [-- EXTRA agrisim run FLAGS]

``--rerender``: COLMAP on the run's views path-traced again by ``agrisim render`` (mitsuba at its
defaults, denoised) into OUT/<plant>[-arms]-mitsuba, the views a user of the photoreal renderer
would make.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402


def _pair(summary: dict, name: str, digits: int) -> str:
    med, top = summary[f"median_{name}"], summary[f"max_{name}"]
    return "-" if med is None else f"{med:.{digits}f} / {top:.{digits}f}"


def main() -> None:
    from agrisim.plugins.plants.procedural.species import SPECIES

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--plants", nargs="+", default=list(SPECIES))
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--shadow-samples", type=int, default=8)
    parser.add_argument("--arms", action="store_true", help="leave the arms in view (default: hidden)")
    parser.add_argument("--matcher", default="exhaustive")
    parser.add_argument(
        "--colmap-flags",
        default="",
        help="more agrisim colmap flags, e.g. '--priors none --peak-threshold 0.0067' (the tables of 2026-11-25)",
    )
    parser.add_argument("--rerender", action="store_true", help="COLMAP on the views path-traced by mitsuba")
    # (argparse mixes up a "--" after an option of several values: split by hand)
    argv = sys.argv[1:]
    cut = argv.index("--") if "--" in argv else len(argv)
    args = parser.parse_args(argv[:cut])
    args.extra = argv[cut + 1 :]
    agrisim = [sys.executable, "-m", "agrisim"]
    print(
        f"CPU: {cpu_model()}; raycast, {args.resolution}, {args.shadow_samples} shadow rays a pixel"
        f"{', path-traced again by agrisim render (mitsuba defaults)' if args.rerender else ''}, "
        f"arms {'in view' if args.arms else 'hidden'}; COLMAP {args.matcher} matching, the run's intrinsics"
        f"{', ' + args.colmap_flags if args.colmap_flags else ''}"
    )
    print(
        "| plant | registered | within 20 mm | centre error mm, median / max | rotation error deg, median / max "
        "| reprojection px | COLMAP s |"
    )
    print("|---|---|---|---|---|---|---|")
    for plant in args.plants:
        run = args.out / (plant + ("-arms" if args.arms else ""))
        if (run / "run.json").exists() and json.loads((run / "run.json").read_text())["status"] != "complete":
            subprocess.run([*agrisim, "run", "--resume", "--out", str(run)], check=True, capture_output=True)
        elif not (run / "run.json").exists():
            flags = ["--plant", plant, "--resolution", args.resolution, "--recon", "none", "--no-rrd"]
            flags += ["--set", f"renderer.raycast.shadow_samples={args.shadow_samples}", "--out", str(run)]
            subprocess.run(
                [*agrisim, "run", *flags, *([] if args.arms else ["--hide-robots"]), *args.extra],
                check=True,
                capture_output=True,
            )
        if args.rerender:
            views = run.with_name(run.name + "-mitsuba")
            done = views / "render.json"
            if not (done.is_file() and json.loads(done.read_text()).get("status") == "complete"):
                subprocess.run([*agrisim, "render", str(run), "--out", str(views)], check=True, capture_output=True)
            run = views
        t0 = time.perf_counter()
        subprocess.run(
            [*agrisim, "colmap", str(run), "--matcher", args.matcher, *args.colmap_flags.split(), "--overwrite"],
            check=True,
            capture_output=True,
        )
        seconds = time.perf_counter() - t0
        s = json.loads((run / "colmap" / "poses.json").read_text())["summary"]
        reproj = "-" if s["reprojection_px"] is None else f"{s['reprojection_px']:.2f}"
        print(
            f"| {plant.replace('_', ' ')} | {s['registered']}/{s['views']} | {s['within_20mm']} | "
            f"{_pair(s, 'centre_error_mm', 1)} | "
            f"{_pair(s, 'rotation_error_deg', 2)} | {reproj} | {seconds:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
