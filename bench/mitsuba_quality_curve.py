"""How close the mitsuba renderer's images come to a converged one, by samples per pixel, with
and without the denoiser: PSNR of the 8-bit sRGB images (what the PNGs hold) against a
``--reference-spp`` render of the same view (another seed), for a few species in the lab.
Prints one row per species and setting, and the seconds each render took here; asserts
nothing. The curve the defaults are chosen from (the kernels' time scales with the samples:
see bench/mitsuba_frame_cost.py for a GPU's).

    python bench/mitsuba_quality_curve.py [--size 480x270] [--plants boston_fern hydrangea indian_cress]
        [--spp 4 8 16 32 64] [--reference-spp 1024] [--max-depths 8] [--variant auto]

On a GPU machine without the denoiser (pyoidn does not fit beside Mitsuba in one carry), render
there and score here: ``--runs RUN...`` takes the scenes saved by runs (no plant building),
``--save DIR`` writes the renders' centre crops (noisy colour, albedo, normal, the reference) as
float16, one file a run, instead of scoring, and ``--score DIR`` denoises and scores what was saved.

    python bench/mitsuba_quality_curve.py --runs A B C --size 1920x1080 --variant cuda --save OUT
    python bench/mitsuba_quality_curve.py --score OUT
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
from agrisim.plugins.plants.procedural import grow  # noqa: E402
from agrisim.plugins.render.mitsuba import integrator as cutout  # noqa: E402
from agrisim.plugins.render.mitsuba.options import MitsubaOptions  # noqa: E402
from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer  # noqa: E402
from agrisim.plugins.rigs.paper.cell import build_cell  # noqa: E402
from agrisim.plugins.rooms.lab.room import build_scene  # noqa: E402
from agrisim.scene.camera import CameraModel  # noqa: E402
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
    parser.add_argument(
        "--integrators",
        nargs="+",
        default=[MitsubaOptions().integrator],
        help="integrators to compare, each against its own reference",
    )
    parser.add_argument("--sampler", default=None, help="Mitsuba sampler of the renders (default: the renderer's)")
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--runs", type=Path, nargs="+", help="scenes of saved runs instead of --plants")
    parser.add_argument("--save", type=Path, help="write the renders' centre crops here instead of scoring")
    parser.add_argument("--score", type=Path, help="denoise and score the crops --save wrote")
    parser.add_argument("--crop", default="480x270", help="centre crop saved with --save")
    parser.add_argument("--references", type=Path, help="reuse the references --save wrote there (same crop)")
    parser.add_argument("--views", nargs="+", default=list(VIEWS), choices=list(VIEWS), help="views of --save")
    args = parser.parse_args()
    if args.score:
        score(args.score)
        return
    W, H = (int(v) for v in args.size.split("x"))
    # the rpi3-wide preset's field of view (fx = 0.7 W) at any size, centred
    camera = CameraModel(W, H, 0.7 * W, 0.7 * W, (W - 1) / 2, (H - 1) / 2)
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

    if args.save:
        save(args, camera)
        return
    cell = build_cell(CellConfig())
    for plant in args.plants:
        scene = build_scene(cell, grow(plant, 0), labels="plant")
        target = scene.mesh("plant").vertices.mean(axis=0)
        T = look_at(target + np.array([0.35, -0.35, 0.3]), target)  # the plant filling the view
        for integrator in args.integrators:
            reference, ref_s = render(scene, T, spp=args.reference_spp, seed=9, denoise="off", integrator=integrator)
            for depth in args.max_depths:
                rows = []
                for spp in args.spp:
                    for denoise in ("on", "off"):
                        image, seconds = render(
                            scene, T, spp=spp, denoise=denoise, max_depth=depth, integrator=integrator
                        )
                        kind = "denoised" if denoise == "on" else "raw"
                        rows.append(f"{spp} {kind} {psnr(image, reference):.1f} dB ({seconds:.2f} s)")
                print(
                    f"{plant}, {integrator}, max depth {depth} (reference {ref_s:.0f} s): " + "; ".join(rows),
                    flush=True,
                )


def _crop(image: np.ndarray, size: str) -> np.ndarray:
    w, h = (int(v) for v in size.split("x"))
    y0, x0 = (image.shape[0] - h) // 2, (image.shape[1] - w) // 2
    return np.ascontiguousarray(image[y0 : y0 + h, x0 : x0 + w])


#: where views look from, relative to the plant's centre: close up, and from further on the other side
VIEWS = {"near": np.array([0.35, -0.35, 0.3]), "far": np.array([-0.5, 0.3, 0.45])}


def save(args: argparse.Namespace, camera: CameraModel) -> None:
    """Render the saved runs' plants from each of VIEWS and write one ``<run>_<view>.npz`` of
    centre crops, float16: the reference, and per samples and path length the colour and the
    integrator's albedo and normal (OIDN denoises and scores them with ``--score``, where pyoidn
    is: it does not fit beside Mitsuba on the GPU machine)."""
    import drjit as dr

    from agrisim.files import layout
    from agrisim.plugins.formats.scene_glb import read_scene
    from agrisim.scene.camera import view_seed

    args.save.mkdir(parents=True, exist_ok=True)
    size = f"{camera.width}x{camera.height}"
    for run in args.runs:
        scene = read_scene(run / layout.SCENE_GLB)
        target = scene.mesh(scene.plant).vertices.mean(axis=0)
        for view in args.views:
            T = look_at(target + VIEWS[view], target)

            def renderer(scene: object = scene, **options: object) -> MitsubaRenderer:
                return MitsubaRenderer(
                    scene, None, RenderConfig(hide_robots=True), MitsubaOptions(variant=args.variant, **options)
                )

            name = f"{run.name}_{view}_{size}.npz"
            if args.references and (args.references / name).is_file():  # (Russian roulette and
                # the sampler leave the converged image as it is: a reference can serve again)
                arrays = {"ref": np.load(args.references / name)["ref"]}
                print(f"{run.name} {view} {size}: reference from {args.references / name}", flush=True)
            else:
                t0 = time.perf_counter()
                ref = renderer(spp=args.reference_spp, seed=9, denoise="off").radiance(camera, T)
                print(f"{run.name} {view} {size}: reference {time.perf_counter() - t0:.1f} s", flush=True)
                arrays = {"ref": _crop(ref, args.crop).astype(np.float16)}
            for depth in args.max_depths:
                for spp in args.spp:
                    r = renderer(spp=spp, denoise="off", max_depth=depth)
                    # the renderer's integrator, returning the denoiser's guides as it does when denoising
                    guided = r.mi.load_dict(
                        {"type": cutout.NAME, "max_depth": depth, "rr_depth": r.options.rr_depth, "guide": True}
                    )
                    sensor = r._placed_sensor(camera, T)
                    seed = view_seed(camera, T, r.options.seed) & 0xFFFFFFFF
                    r._render("image", sensor, seed, guided)  # compiled apart from the timing
                    dr.sync_thread()
                    t0 = time.perf_counter()
                    image = r._render("image", sensor, seed, guided)
                    dr.eval(image)
                    dr.sync_thread()
                    seconds = time.perf_counter() - t0
                    colour, aux = image[..., 0:3], image[..., 3:9]
                    line = f"  {spp} spp, depth {depth}: {1e3 * seconds:.0f} ms of rendering"
                    colour, aux = np.asarray(colour, np.float32), np.asarray(aux, np.float32)
                    key = f"{spp}_d{depth}"
                    arrays[f"colour_{key}"] = _crop(colour, args.crop).astype(np.float16)
                    arrays[f"albedo_{key}"] = _crop(aux[..., 0:3], args.crop).astype(np.float16)
                    arrays[f"normal_{key}"] = _crop(aux[..., 3:6], args.crop).astype(np.float16)
                    arrays[f"seconds_{key}"] = np.float64(seconds)
                    if "path" in args.integrators:  # Mitsuba's own path tracer's time, for comparison
                        line += f" (path: {1e3 * _time_path(renderer(spp=spp, denoise='off', max_depth=depth), camera, T):.0f} ms)"
                    print(line, flush=True)
                    r.close()
            np.savez_compressed(args.save / name, **arrays)


def _time_path(r: MitsubaRenderer, camera: CameraModel, T: np.ndarray) -> float:
    """Seconds of Mitsuba's ``path`` rendering the view (compiled first), the renderer closed."""
    import drjit as dr

    integrator = r.mi.load_dict({"type": "path", "max_depth": r.options.max_depth})
    sensor = r._placed_sensor(camera, T)
    r._render("path", sensor, 1, integrator)
    dr.sync_thread()
    t0 = time.perf_counter()
    dr.eval(r._render("path", sensor, 2, integrator))
    dr.sync_thread()
    seconds = time.perf_counter() - t0
    r.close()
    return seconds


def score(folder: Path) -> None:
    """PSNR of what :func:`save` wrote, raw and denoised (pyoidn, as the renderer calls it)."""
    import pyoidn

    for path in sorted(folder.glob("*.npz")):
        d = np.load(path)
        reference = shown(d["ref"].astype(np.float32))
        keys = sorted(
            (k[len("colour_") :] for k in d.files if k.startswith("colour_")),
            key=lambda k: (int(k.split("_d")[1]), int(k.split("_")[0])),
        )
        rows = []
        for key in keys:
            colour, albedo, normal = (
                np.ascontiguousarray(d[f"{k}_{key}"].astype(np.float32)) for k in ("colour", "albedo", "normal")
            )
            clean = np.asarray(pyoidn.denoise(colour, albedo, normal, hdr=True), np.float32)
            spp, depth = key.split("_d")
            rows.append(
                f"{spp} spp depth {depth}: denoised {psnr(shown(clean), reference):.1f} dB, raw "
                f"{psnr(shown(colour), reference):.1f} dB ({1e3 * float(d[f'seconds_{key}']):.0f} ms)"
            )
        print(f"{path.stem}: " + "; ".join(rows))


if __name__ == "__main__":
    main()
