"""The README's reconstruction figure (``docs/recon.png``): a plant's merged point cloud from the
paper's texture labels and from RepOpa labels, each point coloured by its distance to the true
surface, with the precision that ``metrics.json`` reports. Run: ``python bench/figure_recon.py``.

The views are the paper's hemisphere (robots hidden, no shadows) at a reduced resolution; the
measurement is agrisim's own (:mod:`agrisim.evaluation.metrics`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config  # noqa: E402
from agrisim.evaluation.metrics import GroundTruth, SurfaceDistance  # noqa: E402
from agrisim.evaluation.session import ReconSession  # noqa: E402
from agrisim.evaluation.views import View  # noqa: E402
from agrisim.plant_choice import resolve_plant  # noqa: E402
from agrisim.plugins.recon.pointcloud import PointCloudReconstructor  # noqa: E402
from agrisim.plugins.rigs.paper.cell import (
    build_cell,  # noqa: E402
    hemisphere,  # noqa: E402
)
from agrisim.plugins.rooms.lab.room import build_scene  # noqa: E402
from agrisim.registry import Registry, make_plugin_manager  # noqa: E402
from agrisim.scene.camera import preset  # noqa: E402

MAX_MM = 10.0  # colour scale: distances beyond this are drawn as this


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="basket_grass")
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--out", type=Path, default=Path("docs/recon.png"))
    args = parser.parse_args()

    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    scene = build_scene(cell, resolve_plant(registry, build_config({"plant": args.plant})))
    camera = preset("rpi3-wide-1080p", args.resolution)
    poses = [sp.world_T_camera for sps in hemisphere(cell, RoutineConfig()).values() for sp in sps]
    truth = GroundTruth.sample(scene.mesh(scene.plant), 500_000)
    distance = SurfaceDistance(truth)
    spec = registry.get("renderer", "raycast")

    fig = plt.figure(figsize=(12, 5.6), dpi=110)
    for k, mode in enumerate(("texture", "repopa")):
        renderer = spec.factory(
            scene, cell, RenderConfig(hide_robots=True, seg_mode=mode), spec.options_model(shadow_samples=0)
        )
        session = ReconSession(PointCloudReconstructor(scene.labels), scene.labels, truth, [2.0])
        for i, T in enumerate(poses):
            f = renderer.render(camera, T, {})
            session.add(View(f"v{i}", camera, T, f.stored()))
        result, metrics = session.finish()
        points = result.clouds["plant"].points
        d_mm = distance(points, 1) * 1e3
        row = metrics["labels"]["plant"]
        # both panels show the true plant's box: RepOpa's stray points on the pot, the table and
        # the stands behind the cards lie partly outside it, and are counted in the title
        lo, hi = truth.points.min(axis=0) - 0.02, truth.points.max(axis=0) + 0.02
        inside = np.all((points >= lo) & (points <= hi), axis=1)
        keep = np.random.default_rng(0).permutation(np.flatnonzero(inside))[:60_000]
        keep = keep[np.argsort(d_mm[keep])]  # far points drawn last, on top
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        p = points[keep]
        sc = ax.scatter(
            p[:, 0],
            p[:, 1],
            p[:, 2],
            c=np.minimum(d_mm[keep], MAX_MM),
            cmap="turbo",
            vmin=0,
            vmax=MAX_MM,
            s=0.4,
            linewidths=0,
        )
        ax.view_init(elev=18, azim=-60)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(hi - lo)
        ax.set_axis_off()
        name = "texture labels (the paper's method)" if mode == "texture" else "RepOpa labels (opacity ignored)"
        ax.set_title(
            f"{name}\n{row['pixels']:,} labelled pixels, {row['points']:,} points\n"
            f"precision@2mm {row['precision']['2']:.3f}; {np.count_nonzero(~inside):,} points outside the plant's box",
            fontsize=10,
        )
    cbar = fig.colorbar(sc, ax=fig.axes, shrink=0.6, pad=0.02)
    cbar.set_label(f"distance to the true opaque surface, mm (clipped at {MAX_MM:g})")
    fig.suptitle(
        f"{args.plant.replace('_', ' ')}: 100 views at {camera.width}x{camera.height} merged on a 1 mm grid",
        fontsize=12,
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, bbox_inches="tight")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
