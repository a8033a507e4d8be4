"""The README's depth-sensor figure (``docs/sensors.png``): one view of a plant as the exact
depth and as each sensor measured it, and the merged plant clouds they give, each point
coloured by its distance to the true surface. Made from finished runs of the same plant and
routine with different ``--depth-sensor`` (``bench/sensor_table.py`` leaves them in its OUT):

    python bench/figure_sensors.py RUN_EXACT RUN_SENSOR [RUN_SENSOR ...] [--frame r1_012]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from agrisim.evaluation.metrics import SurfaceDistance  # noqa: E402
from agrisim.plugins.apps.recon import truth_from_run  # noqa: E402
from agrisim.plugins.exporters.rosbag import read_cloud  # noqa: E402

MAX_MM = 10.0  # colour scale of the clouds: distances beyond this are drawn as this


def sensor_name(run: Path) -> str:
    return json.loads((run / "metrics.json").read_text())["depth"].removeprefix("sensor:")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--frame", default="r1_012")
    parser.add_argument("--out", type=Path, default=Path("docs/sensors.png"))
    args = parser.parse_args()

    runs = args.runs
    truth = truth_from_run(runs[0], 500_000)
    assert truth is not None, "the run has no plant.glb to measure against"
    distance = SurfaceDistance(truth)
    lo, hi = truth.points.min(axis=0) - 0.02, truth.points.max(axis=0) + 0.02
    n = len(runs)
    fig = plt.figure(figsize=(4.0 * (n + 1), 7.0), dpi=100)
    rgb = np.asarray(Image.open(runs[0] / "rgb" / f"{args.frame}.png"))
    ax = fig.add_subplot(2, n + 1, 1)
    ax.imshow(rgb)
    ax.set_title(f"{args.frame}, RGB", fontsize=10)
    ax.set_axis_off()
    exact = np.asarray(Image.open(runs[0] / "depth" / f"{args.frame}.png")).astype(float) / 1000
    near, far = np.percentile(exact[exact > 0], [1, 99])
    clouds = []
    for k, run in enumerate(runs):
        name = sensor_name(run)
        folder = run / ("depth" if name == "exact" else "depth_sensor")
        depth = np.asarray(Image.open(folder / f"{args.frame}.png")).astype(float) / 1000
        shown = np.ma.masked_equal(depth, 0.0)
        cmap = plt.get_cmap("turbo").copy()
        cmap.set_bad("black")
        ax = fig.add_subplot(2, n + 1, k + 2)
        ax.imshow(shown, cmap=cmap, vmin=near, vmax=far)
        valid = (depth > 0).mean()
        ax.set_title(f"{name} depth\n{valid:.0%} of pixels measured (black: none)", fontsize=10)
        ax.set_axis_off()

        metrics = json.loads((run / "metrics.json").read_text())["labels"]["plant"]
        points, _ = read_cloud(run / "clouds" / "plant.ply")
        d_mm = distance(points, 1) * 1e3
        inside = np.all((points >= lo) & (points <= hi), axis=1)
        keep = np.random.default_rng(0).permutation(np.flatnonzero(inside))[:60_000]
        keep = keep[np.argsort(d_mm[keep])]
        ax = fig.add_subplot(2, n + 1, n + 1 + k + 2, projection="3d")
        clouds.append(ax)
        p = points[keep]
        sc = ax.scatter(
            p[:, 0], p[:, 1], p[:, 2], c=np.minimum(d_mm[keep], MAX_MM), cmap="turbo", vmin=0, vmax=MAX_MM, s=0.4,
            linewidths=0,
        )  # fmt: skip
        ax.view_init(elev=18, azim=-60)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(hi - lo, zoom=1.5)
        ax.set_axis_off()
        ax.set_title(
            f"{name}: {metrics['points']:,} points\nprecision@2mm {metrics['precision']['2']:.3f}\n"
            f"recall@2mm {metrics['recall']['2']:.3f}",
            fontsize=9,
        )
    cbar = fig.colorbar(sc, ax=clouds, shrink=0.6, pad=0.02)
    cbar.set_label(f"distance to the true surface, mm (clipped at {MAX_MM:g})")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, bbox_inches="tight")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
