"""The README's traits figure (``docs/traits.png``): four species from above, each leaf's opaque
surface coloured by its inclination (``agrisim.plugins.apps.traits``: exact, cut-outs removed), and under each
its leaf angle distribution (area shares in 10-degree bins) with the nearest of de Wit's classes.
Prints each species' traits; asserts nothing.

    python bench/figure_traits.py [--species coltsfoot amaryllis common_fern boxwood] [--out docs/traits.png]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

from agrisim.plugins.apps.traits.opaque_area import opaque_pieces  # noqa: E402
from agrisim.plugins.apps.traits.truth import INCLINATION_BINS, de_wit_shares, plant_traits  # noqa: E402
from agrisim.plugins.plants.procedural import grow  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--species", nargs="+", default=["coltsfoot", "amaryllis", "common_fern", "boxwood"])
    parser.add_argument("--out", type=Path, default=Path("docs/traits.png"))
    args = parser.parse_args()
    n = len(args.species)
    fig, axes = plt.subplots(2, n, figsize=(3.6 * n, 7.2), gridspec_kw={"height_ratios": [1.3, 1]})
    cmap = plt.get_cmap("viridis")
    for col, name in enumerate(args.species):
        plant = grow(name, 0)
        mesh = plant.mesh
        start = time.perf_counter()
        traits = plant_traits(plant)
        seconds = time.perf_counter() - start
        print(
            f"{name}: {traits.leaf_count} leaves, {traits.leaf_area_m2 * 1e4:.0f} cm^2, height "
            f"{traits.height_m * 100:.1f} cm, mean inclination {traits.mean_inclination_deg:.0f} deg, "
            f"{traits.de_wit_class} ({seconds:.1f} s)",
            flush=True,
        )
        assert mesh.face_instance is not None
        incline = np.zeros(int(mesh.face_instance.max()) + 1)
        for leaf in traits.leaves:
            incline[leaf.id] = leaf.inclination_deg
        leaf_faces = np.flatnonzero(mesh.face_instance > 0)
        polys, colours, heights = [], [], []
        for pieces in opaque_pieces(mesh, faces=leaf_faces):
            for k in range(len(pieces.face)):
                polys.append(pieces.vertices[k, : pieces.count[k], :2] * 100)
            colours.append(incline[mesh.face_instance[pieces.face]])
            heights.append(pieces.centroid[:, 2])
        order = np.argsort(np.concatenate(heights))  # painter's: the highest drawn last
        ax = axes[0, col]
        shown = PolyCollection(
            [polys[i] for i in order],
            array=np.concatenate(colours)[order],
            cmap=cmap,
            clim=(0, 90),
            linewidths=0,
            antialiaseds=False,
        )
        ax.add_collection(shown)
        ax.autoscale_view()
        ax.set_aspect("equal")
        ax.set_title(f"{name.replace('_', ' ')}\n{traits.leaf_count} leaves, {traits.leaf_area_m2 * 1e4:.0f} cm²")
        ax.set_xlabel("x, cm")
        if col == 0:
            ax.set_ylabel("y, cm (from above)")
        bar = axes[1, col]
        centres = (INCLINATION_BINS[:-1] + INCLINATION_BINS[1:]) / 2
        bar.bar(centres, traits.inclination_shares, width=9, color=cmap(centres / 90), label="leaf area")
        kind = traits.de_wit_class
        near = f"de Wit: {kind} (TV {traits.de_wit_distance[kind]:.2f})"
        bar.plot(centres, de_wit_shares(kind), "k.-", label=near)
        bar.set_xlim(0, 90)
        bar.set_xticks(INCLINATION_BINS)
        bar.set_xlabel("leaf inclination, deg")
        if col == 0:
            bar.set_ylabel("share of leaf area")
        bar.legend(fontsize=8, loc="upper right")
    fig.colorbar(shown, ax=axes[0, :].tolist(), shrink=0.8, label="leaf inclination, deg")
    fig.savefig(args.out, dpi=110, bbox_inches="tight")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
