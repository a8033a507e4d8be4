"""Traits measured from a run's views against their truth, a row a species: leaves seen against
leaves there, per-leaf area error (MAPE over the leaves seen), inclination and azimuth errors;
and a plot of estimated against true leaf area (every leaf of every species). Prints the CPU and
the table; asserts nothing. Each species' run goes to OUT/<species>/ (made where missing: the
paper's routine, arms hidden, raycast, ``--resolution``), reused when there.

    python bench/traits_table.py OUT [--species coltsfoot ...] [--resolution 960x540]
        [--depth truth|sensor] [--plot OUT/traits_area.png] [-- EXTRA agrisim run FLAGS]

``--depth sensor`` measures on the run's depth sensor (``-- --depth-sensor d435``).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402


def main() -> None:
    from agrisim.files import layout
    from agrisim.files.plant_asset import load_plant
    from agrisim.plugins.plants.procedural.species import SPECIES
    from agrisim.traits.estimate import leaf_clouds, leaf_estimates
    from agrisim.traits.truth import plant_traits

    argv = sys.argv[1:]
    cut = argv.index("--") if "--" in argv else len(argv)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--species", nargs="+", default=list(SPECIES))
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--depth", choices=["truth", "sensor"], default="truth")
    parser.add_argument("--plot", type=Path)
    args = parser.parse_args(argv[:cut])
    extra = argv[cut + 1 :]
    print(f"CPU: {cpu_model()}; raycast, {args.resolution}, arms hidden, depth: {args.depth} {' '.join(extra)}")
    print("| plant | leaves seen / there | leaf area MAPE | area error range | inclination error deg, mean / max |")
    print("|---|---|---|---|---|")
    pairs: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for species in args.species:
        run = args.out / species
        if not (run / layout.RUN_JSON).is_file():
            flags = ["--plant", species, "--resolution", args.resolution, "--hide-robots", "--recon", "none"]
            subprocess.run(
                [sys.executable, "-m", "agrisim", "run", *flags, "--no-rrd", "--out", str(run), *extra],
                check=True,
                capture_output=True,
            )
        truth = {leaf.id: leaf for leaf in plant_traits(load_plant(run / layout.PLANT_GLB, place=False)).leaves}
        seen = [e for e in leaf_estimates(leaf_clouds(run, depth=args.depth)) if e.id in truth]
        true_area = np.array([truth[e.id].area_m2 for e in seen])
        area = np.array([e.area_m2 for e in seen])
        error = area / true_area - 1.0
        incline = np.abs(np.array([e.inclination_deg - truth[e.id].inclination_deg for e in seen]))
        pairs[species] = (true_area, area)
        print(
            f"| {species.replace('_', ' ')} | {len(seen)} / {len(truth)} | {100 * np.abs(error).mean():.1f}% "
            f"| {100 * error.min():+.1f}% to {100 * error.max():+.1f}% | {incline.mean():.1f} / {incline.max():.1f} |",
            flush=True,
        )
    if args.plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5.5, 5.5))
        top = 0.0
        for species, (true_area, area) in pairs.items():
            ax.scatter(true_area * 1e4, area * 1e4, s=8, label=species.replace("_", " "))
            top = max(top, float(true_area.max(initial=0.0)), float(area.max(initial=0.0)))
        ax.plot([0, top * 1e4], [0, top * 1e4], "k-", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("true leaf area, cm² (agrisim traits)")
        ax.set_ylabel(f"estimated leaf area, cm² (views, {args.depth} depth)")
        ax.legend(fontsize=7)
        fig.savefig(args.plot, dpi=120, bbox_inches="tight")
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
