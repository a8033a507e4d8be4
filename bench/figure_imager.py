"""The README's imager figure (``docs/imager.png``): one view of a finished run re-rendered by
``raycast`` through the Camera Module 3 Wide's lens, as the renderer draws it (noise-free) and
as the IMX708 imager makes it in a lab at 1000 lux and in a dim room at 30 lux (auto-exposure
at its longest time, then gain; JPEG at quality 75), each with a zoom on the plant; and the
photon transfer curve of the IMX708's green pixels (variance against mean of flat fields) with
the model it follows.

    python bench/figure_imager.py RUN_DIR [--frame r1_012] [--resolution 960x540]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from saved_run import frame_pose  # noqa: E402

from agrisim.config import RenderConfig  # noqa: E402
from agrisim.files import layout  # noqa: E402
from agrisim.plugins.formats.scene_glb import read_scene  # noqa: E402
from agrisim.plugins.imagers.pipeline import IMAGERS, ImagePipeline, bayer_sites  # noqa: E402
from agrisim.plugins.render.raycast import RaycastOptions  # noqa: E402
from agrisim.plugins.render.raycast.renderer import RaycastRenderer  # noqa: E402
from agrisim.scene.camera import preset  # noqa: E402


def photon_transfer(pipe: ImagePipeline, gain: float) -> tuple[np.ndarray, np.ndarray]:
    """(mean above black, temporal variance) in DN of a flat grey card's green sites over
    exposure times up to saturation, by EMVA 1288's pair difference."""
    grey = np.full((256, 256, 3), 0.5, np.float32)
    green = bayer_sites(256, 256) == 1
    k = pipe.imager.conversion_gain * gain
    saturate = (pipe.imager.white_level - pipe.imager.black_level) / k / (pipe.imager.electrons_per_s(pipe.lux) * 0.5)
    means, variances = [], []
    for i, t in enumerate(np.geomspace(saturate * 1e-3, saturate * 1.5, 40)):
        e = pipe.electrons(grey, float(t))
        a, b = (pipe.read_out(e, gain, np.random.default_rng([i, j])).astype(np.float64)[green] for j in (0, 1))
        means.append(0.5 * (a.mean() + b.mean()) - pipe.imager.black_level)
        variances.append(0.5 * np.var(a - b))
    return np.array(means), np.array(variances)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--frame", default="r1_012")
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--out", type=Path, default=Path("docs/imager.png"))
    args = parser.parse_args()

    T, poses = frame_pose(args.run_dir, args.frame)
    renderer = RaycastRenderer(
        read_scene(args.run_dir / layout.SCENE_GLB),
        None,
        RenderConfig(),
        RaycastOptions(shadow_samples=16, supersample=2, radiance=True),
    )
    camera = preset("rpi-camera-3-wide", args.resolution)
    frame = renderer.render(camera, T, poses)
    assert frame.radiance is not None
    imx708 = IMAGERS["imx708"]
    shots = [("renderer, noise-free (--imager none)", frame.rgb, "")]
    for lux, quality in ((1000.0, 0), (30.0, 75)):
        shot = ImagePipeline(imx708, lux=lux, jpeg_quality=quality).shoot(frame.radiance, 0)
        e = shot.exposure
        jpeg = f", JPEG {quality}" if quality else ""
        shots.append((f"IMX708 at {lux:g} lx{jpeg}", shot.rgb, f"{e.time_s * 1e3:.1f} ms, gain {e.gain:.1f}"))

    on = np.argwhere(frame.labels > 0)
    (y0, x0), (y1, x1) = on.min(0), on.max(0)
    cy, cx, half = (y0 + y1) // 2, (x0 + x1) // 2, max(24, (y1 - y0) // 5)

    fig = plt.figure(figsize=(15, 6.2), dpi=80)
    grid = fig.add_gridspec(2, 4, width_ratios=[1, 1, 1, 1.1])
    for col, (title, rgb, note) in enumerate(shots):
        ax, zoom = fig.add_subplot(grid[0, col]), fig.add_subplot(grid[1, col])
        ax.imshow(rgb)
        ax.set_title(title + (f"\n{note}" if note else "\n"), fontsize=10)
        zoom.imshow(rgb[cy - half : cy + half, cx - half : cx + half], interpolation="nearest")
        zoom.set_title("the plant, pixel for pixel", fontsize=9)
        for a in (ax, zoom):
            a.set_xticks([])
            a.set_yticks([])
    ptc = fig.add_subplot(grid[:, 3])
    pipe = ImagePipeline(imx708)
    for gain, colour in ((1.0, "tab:green"), (8.0, "tab:purple")):
        mean, var = photon_transfer(pipe, gain)
        k = imx708.conversion_gain * gain
        ptc.loglog(np.maximum(mean, 0.1), var, "o", ms=3, color=colour, label=f"gain {gain:g}: measured")
        model = np.geomspace(0.1, mean.max(), 100)
        ptc.loglog(model, k * model + (imx708.read_noise_e * k) ** 2 + 1 / 12, "-", color=colour, lw=1)
    ptc.set_xlabel("mean signal above black, DN")
    ptc.set_ylabel("temporal variance, DN$^2$")
    ptc.set_title("IMX708 photon transfer, green sites\nlines: K mean + (read noise)$^2$ + 1/12", fontsize=10)
    ptc.legend(fontsize=8, loc="upper left")
    ptc.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
