"""The reconstruction table on depth sensors: each species run at the paper's routine with each
sensor (``--depth-sensor``), reconstructed as point clouds (the run's own) and by TSDF fusion
(``agrisim recon --recon tsdf``), measured against the true plant surface. Prints a Markdown
table; asserts nothing. Runs are kept under OUT and reused when complete (``--resume``).

    python bench/sensor_table.py OUT [--plants all] [--sensors exact,azure-kinect-nfov]
                                     [--setpoints 5x10] [--resolution 1920x1080]

Columns: the share of the plant's pixels with a measured depth (``valid``), the points of the
merged plant cloud, precision and recall at 1, 2 and 5 mm, and the Chamfer distance (mm).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model  # noqa: E402


def agrisim(*args: str) -> None:
    done = subprocess.run([sys.executable, "-m", "agrisim", *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"agrisim {' '.join(args)} failed:\n{done.stderr}")


def valid_share(run: Path) -> float:
    """Of the plant's pixels (labels > 0), the share with a depth the sensor measured."""
    folder = run / "depth_sensor" if (run / "depth_sensor").is_dir() else run / "depth"
    plant = measured = 0
    for labels in sorted((run / "labels").glob("*.png")):
        on = np.asarray(Image.open(labels)) > 0
        depth = np.asarray(Image.open(folder / labels.name))
        plant += int(on.sum())
        measured += int((on & (depth > 0)).sum())
    return measured / max(plant, 1)


def row(species: str, sensor: str, recon: str, metrics: dict, valid: float) -> str:
    m = metrics["labels"]["plant"]
    p, r = m["precision"], m["recall"]
    return (
        f"| {species} | {sensor} | {recon} | {valid:.1%} | {m['points']:,} | "
        + " | ".join(f"{p[t]:.3f} / {r[t]:.3f}" for t in ("1", "2", "5"))
        + f" | {m['chamfer_mm']:.2f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--plants", default="all")
    parser.add_argument("--sensors", default="exact,azure-kinect-nfov")
    parser.add_argument("--setpoints", default="5x10")
    parser.add_argument("--resolution", default="1920x1080")
    args = parser.parse_args()

    from agrisim.plugins.plants.procedural.species import SPECIES

    plants = sorted(SPECIES) if args.plants == "all" else args.plants.split(",")
    sensors = args.sensors.split(",")
    print(f"CPU: {cpu_model()}; setpoints {args.setpoints}, {args.resolution}")
    lines = [
        "| species | sensor | reconstruction | valid plant pixels | points | P / R @1 mm | P / R @2 mm | P / R @5 mm | Chamfer mm |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for species in plants:
        for sensor in sensors:
            run = args.out / f"{species}-{sensor}"
            t0 = time.perf_counter()
            if not (run / "metrics.json").is_file():
                agrisim(
                    "run", "--plant", species, "--depth-sensor", sensor, "--setpoints", args.setpoints,
                    "--resolution", args.resolution, "--no-rrd", "--out", str(run),
                    *(["--resume"] if run.exists() else []),
                )  # fmt: skip
            if not (run / "tsdf" / "metrics.json").is_file():
                agrisim("recon", str(run), "--recon", "tsdf", "--out", str(run / "tsdf"), "--overwrite")
            valid = valid_share(run)
            for recon, folder in (("points", run), ("TSDF", run / "tsdf")):
                metrics = json.loads((folder / "metrics.json").read_text())
                lines.append(row(species, sensor, recon, metrics, valid))
            print(f"{species} {sensor}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
