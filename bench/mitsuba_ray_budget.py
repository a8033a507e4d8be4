"""How many rays a ``cutout_path`` view casts, and the least time those rays take cast alone:
the floor under a view's kernels on this device, whatever the shading costs.

For a few views of a saved run it counts the ray casts of the integrator by kind (the camera
ray and its walk past cut-out texels; bounces and their walks; shadow rays and their walks),
times the same render uncounted, and times ray casts with nothing else in the kernel: the 1080p
camera rays at the render's samples per pixel (coherent), and rays from where those hit in
cosine-distributed directions (incoherent, as bounces and shadow rays are). The floor is the
camera casts at the coherent rate plus the rest at the incoherent one. Prints figures; asserts
nothing. Runs from a minimal install (no Open3D).

    python bench/mitsuba_ray_budget.py RUN_DIR [--variant cuda] [--spp 8] [--frames 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402
from saved_run import saved_run  # noqa: E402

from agrisim.plugins.apps.render import _link_poses  # noqa: E402
from agrisim.plugins.render.mitsuba import integrator as cut  # noqa: E402
from agrisim.plugins.render.mitsuba.options import MitsubaOptions  # noqa: E402
from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer  # noqa: E402
from agrisim.scene.camera import view_seed  # noqa: E402

KINDS = ("camera ray + walk", "bounces + walks", "shadow rays + walks")
counting = False  # read while the integrator is traced (freeze is off: traced every render)
counter: Any = None


class Counted:
    """The scene as ``_kept`` and ``_visible`` see it: every ray cast adds one to ``counter[kind]``
    (inside Dr.Jit's symbolic loops and conditionals the scatter is masked as the cast is)."""

    def __init__(self, scene: Any, kind: int) -> None:
        self.scene, self.kind = scene, kind

    def ray_intersect_preliminary(self, ray: Any, coherent: bool = False, active: Any = True) -> Any:
        import drjit as dr
        import mitsuba as mi

        # (one per lane: a value, index and mask of width 1 would make a scatter of width 1)
        ones = dr.full(mi.UInt32, 1, dr.width(ray.d))
        dr.scatter_reduce(dr.ReduceOp.Add, counter, ones, mi.UInt32(self.kind), active)
        return self.scene.ray_intersect_preliminary(ray, coherent=coherent, active=active)


def patched() -> type:
    cls = base()

    class Probe(cls):
        def _kept(self, scene: Any, ray: Any, active: Any, coherent: bool = False) -> Any:
            if counting:
                scene = Counted(scene, 0 if coherent else 1)
            return super()._kept(scene, ray, active, coherent)

        def _visible(self, scene: Any, ray: Any, target: Any, active: Any) -> Any:
            return super()._visible(Counted(scene, 2) if counting else scene, ray, target, active)

    return Probe


base = cut._integrator_class
cut._integrator_class = patched


def timed(fn: Any, repeat: int = 5) -> float:
    """Median seconds of ``fn()`` evaluated and synchronised (Dr.Jit runs asynchronously)."""
    import drjit as dr

    times = []
    for _ in range(repeat + 1):
        t = time.perf_counter()
        dr.eval(fn())
        dr.sync_thread()
        times.append(time.perf_counter() - t)
    return float(np.median(times[1:]))  # the first compiles


def cast_rates(renderer: MitsubaRenderer, sensor: Any, n_pixels: int, spp: int) -> tuple[float, float]:
    """Seconds a ray, (coherent camera rays, incoherent rays from their hits), cast alone."""
    import drjit as dr

    mi = renderer.mi
    width, height = sensor.film().crop_size()
    n = n_pixels * spp
    idx = dr.arange(mi.UInt32, n)
    rng = mi.PCG32(size=n, initstate=idx)
    pixel = idx // spp
    pos = mi.Point2f(
        (mi.Float(pixel % width) + rng.next_float32()) / width,
        (mi.Float(pixel // width) + rng.next_float32()) / height,
    )
    rays, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5))
    dr.eval(rays)
    scene = renderer.mi_scene
    t_coherent = timed(lambda: scene.ray_intersect_preliminary(rays, coherent=True).t)
    si = scene.ray_intersect(rays)
    d = si.to_world(mi.warp.square_to_cosine_hemisphere(mi.Point2f(rng.next_float32(), rng.next_float32())))
    bounced = si.spawn_ray(d)
    valid = si.is_valid()
    dr.eval(bounced, valid)
    n_valid = int(dr.count(valid)[0])
    t_incoherent = timed(lambda: scene.ray_intersect_preliminary(bounced, active=valid).t)
    return t_coherent / n, t_incoherent / max(n_valid, 1)


def main() -> None:
    global counting, counter
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--spp", type=int, default=MitsubaOptions().spp)
    parser.add_argument("--frames", type=int, default=3)
    args = parser.parse_args()
    saved = saved_run(args.run_dir)
    cameras, camera = saved.cameras, saved.camera
    options = MitsubaOptions(spp=args.spp, variant=args.variant, denoise="off", freeze="off")
    renderer = MitsubaRenderer(saved.scene, None, saved.settings, options)
    import drjit as dr

    mi = renderer.mi
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}; variant {mi.variant()}")
    n_pixels = camera.width * camera.height
    print(
        f"{camera.width}x{camera.height}, {options.integrator}, {args.spp} spp, {options.sampler}, max depth {options.max_depth}, rr depth {options.rr_depth}"
    )
    frames = sorted(cameras["frames"])[:: max(1, len(cameras["frames"]) // args.frames)][: args.frames]
    for f in frames:
        renderer._place_arms(_link_poses(args.run_dir, f))
        pose = np.asarray(cameras["frames"][f]["world_T_camera"], np.float64)
        sensor = renderer._placed_sensor(camera, pose)
        seed = view_seed(camera, pose, options.seed) & 0xFFFFFFFF
        counting = False
        t_render = timed(lambda s=sensor, k=seed: renderer._render("image", s, k), repeat=3)
        counting = True
        counter = dr.zeros(mi.UInt32, len(KINDS))
        dr.eval(renderer._render("image", sensor, seed))
        dr.sync_thread()
        counts = np.asarray(counter, np.float64)
        counting = False
        spp = sensor.sampler().sample_count()
        t_coherent, t_incoherent = cast_rates(renderer, sensor, n_pixels, spp)
        floor = counts[0] * t_coherent + counts[1:].sum() * t_incoherent
        per_sample = counts / (n_pixels * spp)
        kinds = ", ".join(
            f"{k} {c / 1e6:.1f} M ({s:.2f} a sample)" for k, c, s in zip(KINDS, counts, per_sample, strict=True)
        )
        print(
            f"view {f}: {spp} spp; {counts.sum() / 1e6:.1f} M casts: {kinds}; render (traced anew + kernels) {1e3 * t_render:.0f} ms "
            f"({counts.sum() / t_render / 1e9:.2f} G casts/s); cast alone: coherent {1e9 * t_coherent:.2f} ns, "
            f"incoherent {1e9 * t_incoherent:.2f} ns a ray; floor {1e3 * floor:.0f} ms "
            f"({100 * floor / t_render:.0f}% of the render)"
        )
    renderer.close()


if __name__ == "__main__":
    main()
