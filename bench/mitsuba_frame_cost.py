"""Where one ``mitsuba`` view's time goes, from a saved run, on the GPU or the CPU: per frame the
arms and the sensor moved, ``mi.render`` traced and launched (Python), its kernels, the guide
pass (albedo and normals for the denoiser), the denoiser, the copy to host, the 8-bit encoding
and the PNG; the renderer's own steps with ``freeze`` off, then on (``dr.freeze``: the kernels
recorded and replayed), and whether the frozen images are the traced ones bit for bit. Prints figures; asserts nothing. Runs from a minimal install (no Open3D).

    python bench/mitsuba_frame_cost.py RUN_DIR [--variant cuda] [--spp 16] [--frames 10] [--denoise off] [--max-depth 8]
        [--loops symbolic|evaluated] [--jit-flag NAME=0|1 ...]

``--loops`` chooses how Dr.Jit runs the integrator's loops (issue 50's first lever): ``symbolic``
(the default: one megakernel, every lane waiting for the longest path and cut-out walk) or
``evaluated`` (a kernel an iteration, the loop state in memory). Dr.Jit's ``CompressLoops``
(finished lanes dropped after each iteration) refuses the integrator: its cut-out walks are loops
inside the path's loop, and a compressed inner loop changes its state's size.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402
from saved_run import saved_run  # noqa: E402

from agrisim.files.png import encode_png  # noqa: E402
from agrisim.plugins.apps.render import _link_poses  # noqa: E402
from agrisim.plugins.render.mitsuba import denoise  # noqa: E402
from agrisim.plugins.render.mitsuba.options import MitsubaOptions  # noqa: E402
from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer  # noqa: E402
from agrisim.scene.camera import view_seed  # noqa: E402
from agrisim.scene.colour import encode_srgb8  # noqa: E402


class Clock:
    """Seconds per named step, summed over frames."""

    def __init__(self) -> None:
        self.total: dict[str, float] = {}
        self.t = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.total[name] = self.total.get(name, 0.0) + now - self.t
        self.t = now


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--denoise", default="off")
    parser.add_argument("--integrator", default=MitsubaOptions().integrator, choices=["cutout_path", "path", "volpath"])
    parser.add_argument("--sampler", default=MitsubaOptions().sampler, choices=["multijitter", "independent"])
    parser.add_argument("--max-depth", type=int, default=MitsubaOptions().max_depth)
    parser.add_argument("--loops", default="symbolic", choices=["symbolic", "evaluated"])
    parser.add_argument(
        "--jit-flag", action="append", default=[], metavar="NAME=0|1", help="a Dr.Jit flag set (dr.JitFlag.NAME)"
    )
    args = parser.parse_args()
    saved = saved_run(args.run_dir)
    cameras, settings, scene, camera = saved.cameras, saved.settings, saved.scene, saved.camera
    options = MitsubaOptions(
        spp=args.spp,
        variant=args.variant,
        denoise=args.denoise,
        integrator=args.integrator,
        sampler=args.sampler,
        max_depth=args.max_depth,
    )
    import drjit as dr

    if args.loops == "evaluated":
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
    for item in args.jit_flag:
        name, _, value = item.partition("=")
        dr.set_flag(getattr(dr.JitFlag, name), value not in ("0", "false", "False"))
    frames = sorted(cameras["frames"])[: args.frames + 1]  # the first compiles: reported apart
    poses = {f: np.asarray(cameras["frames"][f]["world_T_camera"], np.float64) for f in frames}
    links = {f: _link_poses(args.run_dir, f) for f in frames}

    def frames_of(renderer: MitsubaRenderer) -> tuple[Clock, Clock, dict[str, np.ndarray]]:
        """The renderer's own steps for every frame, timed (first frame apart), and the images."""
        o = renderer.options
        images: dict[str, np.ndarray] = {}
        first = clock = Clock()
        for i, f in enumerate(frames):
            if i == 1:
                clock = Clock()
            renderer._place_arms(links[f])
            sensor = renderer._placed_sensor(camera, poses[f])
            dr.sync_thread()
            clock.lap("arms posed + sensor moved")
            seed = view_seed(camera, poses[f], o.seed) & 0xFFFFFFFF
            image = renderer._render("image", sensor, seed)
            clock.lap("render traced or replayed + launched (Python)")
            dr.eval(image)
            dr.sync_thread()
            clock.lap("path-tracing kernels")
            if renderer.denoise:
                colour, aux = renderer._guides(image, sensor, seed)
                dr.eval(colour, aux)
                dr.sync_thread()
                clock.lap("guides split" if renderer.guided else "guide pass")
                linear = denoise.denoise(colour, aux)
                clock.lap("denoise + copy to host")
            else:
                linear = np.asarray(image, np.float32)[..., :3]
                clock.lap("copy to host")
            rgb = srgb8(linear, o.exposure, o.tonemap)
            clock.lap("8-bit encoding")
            encode_png(rgb)
            clock.lap("PNG")
            images[f] = linear
        return first, clock, images

    # one renderer at a time: a second scene on the device slowed the first's tracing (H100)
    traced = MitsubaRenderer(scene, None, settings, options.model_copy(update={"freeze": "off"}))
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}; variant {traced.mi.variant()}")
    print(
        f"{camera.width}x{camera.height}, {args.integrator}, max depth {args.max_depth}, {args.spp} spp, "
        f"{args.sampler}, denoise {'on' if traced.denoise else 'off'}, {args.loops} loops, {args.jit_flag or 'default'} "
        "Dr.Jit flags, "
        f"{len(frames) - 1} frames after the first"
    )
    first, clock, plain = frames_of(traced)
    report("traced anew", first, clock, len(frames) - 1)
    traced.close()
    frozen = MitsubaRenderer(scene, None, settings, options.model_copy(update={"freeze": "on"}))
    first, clock, replayed = frames_of(frozen)
    report("frozen", first, clock, len(frames) - 1)
    same = sum(int(np.array_equal(replayed[f], plain[f])) for f in frames)
    recordings = frozen._frozen["image"].n_recordings
    print(f"frozen images equal to traced ones bit for bit: {same} of {len(frames)}; recordings made: {recordings}")
    if not frozen.denoise:
        per, overlapped = streamed(frozen, camera, frames, poses, links)
        o = frozen.options
        same = sum(int(np.array_equal(overlapped[f], srgb8(plain[f], o.exposure, o.tonemap))) for f in frames)
        print(
            f"frozen, the next view launched before this one is read back: {1e3 * per:.1f} ms a view "
            f"({1 / per:.2f} views/s); images equal to the traced ones: {same} of {len(frames)}"
        )
    frozen.close()


def streamed(
    renderer: MitsubaRenderer,
    camera: Any,
    frames: list[str],
    poses: dict[str, np.ndarray],
    links: dict[str, Any],
) -> tuple[float, dict[str, np.ndarray]]:
    """Seconds a view, from the first image handed over to the last, through the renderer's own
    ``render_rgb_stream`` (each view launched before the previous one is read back and
    encoded), the PNGs written in a thread as ``agrisim render`` does; and the sRGB images. The
    second view is launched before the clock starts, so a steady figure wants ``--frames 5`` or
    more."""
    images: dict[str, np.ndarray] = {}
    start = 0.0
    views = ((poses[f], links[f]) for f in frames)
    with ThreadPoolExecutor(1) as writer:
        for i, (f, (rgb, _)) in enumerate(zip(frames, renderer.render_rgb_stream(camera, views), strict=True)):
            if i == 0:
                start = time.perf_counter()
            writer.submit(encode_png, rgb)
            images[f] = rgb
    return (time.perf_counter() - start) / max(len(frames) - 1, 1), images


def srgb8(linear: np.ndarray, exposure: float, tonemap: str) -> np.ndarray:
    """H x W x 3 linear RGB as the renderer encodes it to 8-bit sRGB."""
    rgb = np.empty((linear.shape[0] * linear.shape[1], 3), np.uint8)
    encode_srgb8(np.array(linear, np.float32).reshape(-1, 3), rgb, exposure, tonemap)
    return rgb.reshape(linear.shape[0], linear.shape[1], 3)


def report(what: str, first: Clock, clock: Clock, n: int) -> None:
    per = {k: v / max(n, 1) for k, v in clock.total.items()}
    total = sum(per.values())
    parts = ", ".join(f"{k} {1e3 * v:.1f}" for k, v in per.items())
    print(
        f"{what}: first frame {sum(first.total.values()):.2f} s; then {1e3 * total:.1f} ms a view ({1 / total:.2f} views/s): {parts} ms"
    )


if __name__ == "__main__":
    main()
