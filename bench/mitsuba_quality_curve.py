"""How close the mitsuba renderer's images come to a converged one, by samples per pixel, with
and without the denoiser: PSNR of the 8-bit sRGB images (what the PNGs hold) against a
``--reference-spp`` render of the same view (another seed), for a few species in the lab.
Prints one row per species and setting, and the seconds each render took here; asserts
nothing. The curve the defaults are chosen from (the kernels' time scales with the samples:
see bench/mitsuba_frame_cost.py for a GPU's).

    python bench/mitsuba_quality_curve.py [--size 480x270] [--plants boston_fern hydrangea indian_cress]
        [--spp 4 8 16 32 64] [--reference-spp 1024] [--max-depths 8] [--variant auto]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402

from agrisim.config import CellConfig, RenderConfig  # noqa: E402
from agrisim.lab.room import build_scene  # noqa: E402
from agrisim.plugins.plants.procedural import grow  # noqa: E402
from agrisim.plugins.render.mitsuba.options import MitsubaOptions  # noqa: E402
from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer  # noqa: E402
from agrisim.scene.camera import CameraModel  # noqa: E402
from agrisim.scene.cell import build_cell  # noqa: E402
from agrisim.scene.colour import encode_srgb8  # noqa: E402
from agrisim.scene.transforms import look_at  # noqa: E402


def shown(radiance: np.ndarray) -> np.ndarray:
    """The 8-bit sRGB image of linear ``radiance`` (a copy: the encoder works in place)."""
    out = np.empty((radiance.shape[0] * radiance.shape[1], 3), np.uint8)
    encode_srgb8(np.array(radiance, np.float32).reshape(-1, 3), out, 1.0, "clip")
    return out.astype(np.float64)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(((a - b) ** 2).mean())
    return 10 * np.log10(255.0**2 / mse) if mse > 0 else float("inf")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="480x270")
    parser.add_argument("--plants", nargs="+", default=["boston_fern", "hydrangea", "indian_cress"])
    parser.add_argument("--spp", type=int, nargs="+", default=[4, 8, 16, 32, 64])
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument(
        "--max-depths",
        type=int,
        nargs="+",
        default=[MitsubaOptions().max_depth],
        help="path lengths to try (the reference keeps the default)",
    )
    parser.add_argument("--variant", default="auto")
    args = parser.parse_args()
    W, H = (int(v) for v in args.size.split("x"))
    # the rpi3-wide preset's field of view (fx = 0.7 W) at any size, centred
    camera = CameraModel(W, H, 0.7 * W, 0.7 * W, (W - 1) / 2, (H - 1) / 2)
    cell = build_cell(CellConfig())
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}; {W}x{H}; reference {args.reference_spp} spp")

    def render(scene, T: np.ndarray, **options) -> tuple[np.ndarray, float]:  # noqa: ANN001
        r = MitsubaRenderer(
            scene, None, RenderConfig(hide_robots=True), MitsubaOptions(variant=args.variant, **options)
        )
        t0 = time.perf_counter()
        image = r.radiance(camera, T)
        seconds = time.perf_counter() - t0
        r.close()
        return shown(image), seconds

    for plant in args.plants:
        scene = build_scene(cell, grow(plant, 0), labels="plant")
        target = scene.mesh("plant").vertices.mean(axis=0)
        T = look_at(target + np.array([0.35, -0.35, 0.3]), target)  # the plant filling the view
        reference, ref_s = render(scene, T, spp=args.reference_spp, seed=9, denoise="off")
        for depth in args.max_depths:
            rows = []
            for spp in args.spp:
                for denoise in ("on", "off"):
                    image, seconds = render(scene, T, spp=spp, denoise=denoise, max_depth=depth)
                    kind = "denoised" if denoise == "on" else "raw"
                    rows.append(f"{spp} {kind} {psnr(image, reference):.1f} dB ({seconds:.2f} s)")
            print(f"{plant}, max depth {depth} (reference {ref_s:.0f} s): " + "; ".join(rows), flush=True)


if __name__ == "__main__":
    main()
