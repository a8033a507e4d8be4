"""Traits measured from a run's views against their truth, for each species and each depth
sensor: leaves seen and clustered against leaves there, per-leaf area error (MAPE over the leaves
seen), inclination error, height and hull error (:mod:`agrisim.traits.scores`); and a plot of
estimated against true leaf area, on exact depth and on one sensor. Prints the CPU and Markdown
tables; asserts nothing.

Runs are OUT/<species>-<sensor>/, as ``bench/sensor_table.py`` makes them (the paper's routine
with ``--depth-sensor``; made here where missing), so the two tables can share their runs. Each
run's scores are kept in OUT/traits_table.json and reused (``--again`` measures anew).

    python bench/traits_table.py OUT [--plants all] [--sensors exact,azure-kinect-nfov,d435,d415,d405]
        [--setpoints 5x10] [--resolution 960x540] [--plot docs/traits_area.png] [--plot-sensor d435]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

SENSORS = "exact,azure-kinect-nfov,d435,d415,d405"


def _truth(run: Path) -> Any:
    """The run's plant traits, grown again from its config (its own seed) in the plant frame."""
    from agrisim.config import build_config
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.scene.plant_choice import resolve_plant
    from agrisim.traits.truth import plant_traits

    config = build_config(json.loads((run / "run.json").read_text())["config"])
    return plant_traits(resolve_plant(Registry(make_plugin_manager()), config))


def _make_run(run: Path, species: str, sensor: str, setpoints: str, resolution: str) -> None:
    args = ["run", "--plant", species, "--depth-sensor", sensor, "--setpoints", setpoints]
    args += ["--resolution", resolution, "--no-rrd", "--out", str(run), *(["--resume"] if run.exists() else [])]
    done = subprocess.run([sys.executable, "-m", "agrisim", *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"agrisim {' '.join(args)} failed:\n{done.stderr}")


def _fmt(x: float, spec: str) -> str:
    return "-" if math.isnan(x) else format(x, spec)


def main() -> None:
    from agrisim.plugins.plants.procedural.species import SPECIES
    from agrisim.traits.estimate import measure
    from agrisim.traits.scores import trait_errors

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--plants", default="all")
    parser.add_argument("--sensors", default=SENSORS)
    parser.add_argument("--setpoints", default="5x10")
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--plot", type=Path)
    parser.add_argument("--plot-sensor", default="d435")
    parser.add_argument("--again", action="store_true", help="measure every run anew")
    args = parser.parse_args()

    plants = sorted(SPECIES) if args.plants == "all" else args.plants.split(",")
    sensors = args.sensors.split(",")
    store = args.out / "traits_table.json"
    kept: dict[str, Any] = {} if args.again or not store.is_file() else json.loads(store.read_text())
    print(f"CPU: {cpu_model()}; setpoints {args.setpoints}, {args.resolution}, sensors {', '.join(sensors)}")
    for species in plants:
        truth = None
        for sensor in sensors:
            key = f"{species}-{sensor}"
            if key in kept:
                continue
            run = args.out / key
            t0 = time.perf_counter()
            if not (run / "metrics.json").is_file():
                _make_run(run, species, sensor, args.setpoints, args.resolution)
            truth = truth or _truth(run)
            estimate = measure(run, depth="sensor")
            true_area = {leaf.id: leaf.area_m2 for leaf in truth.leaves}
            kept[key] = {
                "errors": trait_errors(truth, estimate).to_json(),
                "areas": [[true_area[e.id], e.area_m2] for e in estimate.leaves if e.id in true_area],
                "seconds": time.perf_counter() - t0,
            }
            store.write_text(json.dumps(kept, indent=1))
            print(f"{key}: {kept[key]['seconds']:.0f} s", file=sys.stderr, flush=True)

    first = sensors[0]
    print(f"\nOn {first} depth:\n")
    print(
        "| plant | leaves seen / there | clusters (one leaf) | leaf area MAPE | area error range "
        "| inclination error deg, mean / max | height error mm | hull volume error |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for species in plants:
        e = kept[f"{species}-{first}"]["errors"]
        print(
            f"| {species.replace('_', ' ')} | {e['leaves_seen']} / {e['leaves_there']} "
            f"| {e['clusters']} ({e['clusters_one_leaf']}) | {_fmt(e['area_mape_pct'], '.1f')}% "
            f"| {_fmt(e['area_error_min_pct'], '+.1f')}% to {_fmt(e['area_error_max_pct'], '+.1f')}% "
            f"| {_fmt(e['inclination_error_mean_deg'], '.1f')} / {_fmt(e['inclination_error_max_deg'], '.1f')} "
            f"| {1e3 * e['height_error_m']:+.1f} | {_fmt(e['hull_volume_error_pct'], '+.1f')}% |"
        )
    print("\nEach sensor: leaf area MAPE · inclination error (mean, deg) · height error (mm)\n")
    print("| plant | " + " | ".join(sensors) + " |")
    print("|---" * (len(sensors) + 1) + "|")
    for species in plants:
        cells = []
        for sensor in sensors:
            e = kept[f"{species}-{sensor}"]["errors"]
            cells.append(
                f"{_fmt(e['area_mape_pct'], '.1f')}% · {_fmt(e['inclination_error_mean_deg'], '.1f')} "
                f"· {1e3 * e['height_error_m']:+.0f}"
            )
        print(f"| {species.replace('_', ' ')} | " + " | ".join(cells) + " |")
    if args.plot is not None:
        _plot(args.plot, kept, plants, [first, args.plot_sensor])


def _plot(path: Path, kept: dict[str, Any], plants: list[str], sensors: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    sensors = [s for s in dict.fromkeys(sensors) if all(f"{p}-{s}" in kept for p in plants)]
    fig, axes = plt.subplots(1, len(sensors), figsize=(5.2 * len(sensors), 5.2), squeeze=False)
    for ax, sensor in zip(axes[0], sensors, strict=True):
        pairs = {p: np.array(kept[f"{p}-{sensor}"]["areas"]).reshape(-1, 2) * 1e4 for p in plants}
        top = max(float(a.max(initial=1.0)) for a in pairs.values())
        low = min(float(a[a > 0].min(initial=top)) for a in pairs.values())
        for species, a in pairs.items():
            ax.scatter(a[:, 0], np.maximum(a[:, 1], low), s=9, label=species.replace("_", " "))
        ax.plot([low, top], [low, top], "k-", lw=0.8)
        for band in (0.95, 1.05):
            ax.plot([low, top], [low * band, top * band], "k:", lw=0.6)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("true leaf area, cm² (agrisim traits)")
        ax.set_ylabel("estimated leaf area, cm²")
        ax.set_title("exact depth" if sensor == "exact" else sensor, fontsize=10)
    axes[0][0].legend(fontsize=7)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
