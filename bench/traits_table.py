"""Traits measured from a run's views against their truth, for each species and each depth
sensor: leaves seen and clustered against leaves there, per-leaf area error (MAPE over the leaves
seen), inclination error, height and hull error (:mod:`agrisim.plugins.apps.traits.scores`); and a plot of
estimated against true leaf area, on exact depth and on one sensor. Prints the CPU and Markdown
tables; asserts nothing.

Runs are OUT/<species>-<sensor>/, as ``bench/sensor_table.py`` makes them (the paper's routine
with ``--depth-sensor``; made here where missing), so the two tables can share their runs. Each
run's scores are kept in OUT/traits_table.json and reused (``--again`` measures anew).

    python bench/traits_table.py OUT [--plants all] [--sensors exact,azure-kinect-nfov,d435,d415,d405]
        [--setpoints 5x10] [--resolution 960x540] [--plot docs/traits_area.png] [--plot-sensor d435]
        [--plot-also OTHER/traits_table.json:TITLE]
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
    from agrisim.plant_choice import resolve_plant
    from agrisim.plugins.apps.traits.truth import plant_traits
    from agrisim.registry import Registry, make_plugin_manager

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
    from agrisim.plugins.apps.traits.estimate import measure
    from agrisim.plugins.apps.traits.scores import trait_errors
    from agrisim.plugins.plants.procedural.species import SPECIES

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--plants", default="all")
    parser.add_argument("--sensors", default=SENSORS)
    parser.add_argument("--setpoints", default="5x10")
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--plot", type=Path)
    parser.add_argument("--plot-sensor", default="d435")
    parser.add_argument(
        "--plot-also",
        action="append",
        default=[],
        metavar="STORE:TITLE",
        help="another run's traits_table.json, its first sensor drawn as a panel first (say 1920x1080)",
    )
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
        panels = []
        for extra in args.plot_also:
            store_path, _, title = extra.partition(":")
            other = json.loads(Path(store_path).read_text())
            panels.append((title or store_path, other, first))
        panels += [(f"{s} depth, {args.resolution}", kept, s) for s in dict.fromkeys([first, args.plot_sensor])]
        _plot(args.plot, panels, plants)


def _plot(path: Path, panels: list[tuple[str, dict[str, Any], str]], plants: list[str]) -> None:
    """Estimated against true leaf area, a panel each (title, scores, sensor), every species'
    leaves; boxwood's thousands of small leaves drawn faint."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    panels = [(t, k, s) for t, k, s in panels if all(f"{p}-{s}" in k for p in plants)]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.8), squeeze=False)
    for ax, (title, kept, sensor) in zip(axes[0], panels, strict=True):
        pairs = {p: np.array(kept[f"{p}-{sensor}"]["areas"]).reshape(-1, 2) * 1e4 for p in plants}
        low, top = 0.1, 400.0
        for species, a in pairs.items():
            many = len(a) > 1000
            ax.scatter(a[:, 0], np.clip(a[:, 1], low, top), s=3 if many else 10, alpha=0.25 if many else 0.9,
                       label=species.replace("_", " "), rasterized=True)  # fmt: skip
        ax.plot([low, top], [low, top], "k-", lw=0.8)
        for band in (0.95, 1.05):
            ax.plot([low, top], [low * band, top * band], "k:", lw=0.6)
        ax.set(xscale="log", yscale="log", xlim=(low, top), ylim=(low, top), title=title)
        ax.set_xlabel("true leaf area, cm² (agrisim traits)")
        ax.set_ylabel("estimated leaf area, cm²")
    axes[0][0].legend(fontsize=7, markerscale=1.5)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
