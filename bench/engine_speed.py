"""Milliseconds per view of the exact pass (labels, depth, instances) and views per second of the
raycast renderer, on Dr.Jit, re-rendering the views of a saved run. Prints figures; asserts
nothing.

Works from a minimal install (agrisim's core, numpy, pydantic, pluggy, Mitsuba and Dr.Jit): this
is how it is measured on the GPU machine. The first view of each pass compiles the kernels and is
reported apart, with Dr.Jit's own counts of kernels compiled and found in its cache; every later
view is timed to the pixels in host memory (``np.asarray`` of the evaluated arrays), and the
exact pass also to the end of its kernels alone (``dr.eval`` and ``dr.sync_thread``).

    python bench/engine_speed.py RUN_DIR [--variant auto] [--shadow-samples 1] [--views 20]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402

from agrisim.config import RenderConfig  # noqa: E402
from agrisim.files import layout  # noqa: E402
from agrisim.files.rundir import camera_from_json  # noqa: E402
from agrisim.plugins.formats.scene_glb import read_scene  # noqa: E402


def compiled(dr, history: list[dict]) -> str:  # noqa: ANN001
    jit = [k for k in history if k["type"] == dr.KernelType.JIT]
    fresh = [k for k in jit if not k["cache_hit"]]
    return f"{len(jit)} kernels, {len(fresh)} compiled ({sum(k.get('backend_time', 0.0) for k in fresh):.0f} ms in the backend)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--variant", default="auto", choices=["auto", "cuda", "llvm"])
    parser.add_argument("--shadow-samples", type=int, default=1)
    parser.add_argument("--views", type=int, default=20)
    parser.add_argument("--seg-mode", default="texture", choices=["texture", "repopa"])
    args = parser.parse_args()

    import drjit as dr

    from agrisim.plugins.render.raycast import RaycastOptions
    from agrisim.plugins.render.raycast.renderer import RaycastRenderer
    from agrisim.plugins.render.raycast.tracing import SceneTracer, label_map

    cameras = json.loads((args.run_dir / "cameras.json").read_text())
    camera = camera_from_json(cameras["intrinsics"])
    frames = list(cameras["frames"])[: args.views]
    poses = [
        {
            r: {k: np.asarray(T) for k, T in links.items()}
            for r, links in json.loads(layout.link_poses(args.run_dir, f).read_text()).items()
        }
        for f in frames
    ]
    views = [np.asarray(cameras["frames"][f]["world_T_camera"], np.float64) for f in frames]
    t0 = time.perf_counter()
    scene = read_scene(args.run_dir / "scene" / "lab.glb")
    print(
        f"CPU: {cpu_model()}; GPU: {gpu_name()}; scene read in {time.perf_counter() - t0:.1f} s: "
        f"{sum(len(m.faces) for m in scene.meshes):,} static triangles, arms {sorted(scene.arms)}"
    )
    options = RaycastOptions(variant=args.variant, shadow_samples=args.shadow_samples)
    lmap = label_map("organs")

    t0 = time.perf_counter()
    tracer = SceneTracer(scene, None, options, arms=scene.arms)
    import mitsuba

    print(
        f"{camera.width}x{camera.height}, variant {mitsuba.variant()}, {len(views)} views; exact pass built in {time.perf_counter() - t0:.2f} s"
    )

    def exact_kernels(T, p):  # noqa: ANN001, ANN202 - the pass without the copy to the host
        tracer.place_arms(p, (camera, T))
        o, d = tracer.camera_rays(camera, T)
        s = tracer.trace(o, d, raw=args.seg_mode == "repopa")
        out = tracer.annotate(s, args.seg_mode == "repopa", lmap)
        dr.eval(*(x for x in out if x is not None))
        dr.sync_thread()

    for name, step in (
        ("exact pass, kernels only", exact_kernels),
        (
            "exact pass, images in host memory",
            lambda T, p: (
                tracer.place_arms(p, (camera, T)),
                tracer.exact(camera, T, seg_mode=args.seg_mode, label_map=lmap),
            ),
        ),
    ):
        dr.kernel_history()
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            t0 = time.perf_counter()
            step(views[0], poses[0])
            first = time.perf_counter() - t0
            counts = compiled(dr, dr.kernel_history())
            t0 = time.perf_counter()
            for T, p in zip(views[1:], poses[1:], strict=True):
                step(T, p)
            per = (time.perf_counter() - t0) / max(len(views) - 1, 1)
            later = compiled(dr, dr.kernel_history())
        print(
            f"  {name}: first view {first * 1e3:.0f} ms ({counts}); then {per * 1e3:.1f} ms a view ({later} over {len(views) - 1} views)"
        )
    tracer.close()

    t0 = time.perf_counter()
    renderer = RaycastRenderer(scene, None, RenderConfig(hide_robots=False, seg_mode=args.seg_mode), options)
    built = time.perf_counter() - t0
    dr.kernel_history()
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        t0 = time.perf_counter()
        renderer.render(camera, views[0], poses[0])
        first = time.perf_counter() - t0
        counts = compiled(dr, dr.kernel_history())
        t0 = time.perf_counter()
        for T, p in zip(views[1:], poses[1:], strict=True):
            frame = renderer.render(camera, T, p)
        rate = (len(views) - 1) / (time.perf_counter() - t0)
        later = compiled(dr, dr.kernel_history())
    print(
        f"  raycast, {args.shadow_samples} shadow sample(s), RGB + labels + depth in host memory: built in {built:.2f} s, "
        f"first view {first:.2f} s ({counts}); then {rate:.1f} views/s ({later}); mean RGB {frame.rgb.mean():.1f}"
    )


if __name__ == "__main__":
    main()
