"""Where the exact pass's time goes on the CPU, kernel by kernel, at the vector width this CPU
compiles for or at AVX2's (8 lanes, ``--target avx2``: Dr.Jit's LLVM backend retargeted with
``jit_llvm_set_target``, as ``AGRISIM_TEST_CPU=avx2`` does; Embree keeps the kernels it picked
for this CPU, which Mitsuba gives no way to change). Prints figures; asserts nothing.

    python bench/engine_kernels.py RUN_DIR [--target native|avx2] [--views 6] [--threads N]

The pass is cut into stages, each evaluated on its own so that Dr.Jit's kernel history times it
(``execution_time``; the arms' posing by the wall clock, as Embree rebuilds the arms' BVH on
the host): posing the arms; the camera rays; one cast of the static scene and one of the arms
(the walk's first layer alone); the whole walk past cut-out texels and culled faces; the annotations
(labels, instances, depth); the copy to the host. Cut like this the stages cost more than the
fused pass (each stores its outputs); the fused pass is timed too. Every time is the median of
the views after the first (which compiles).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--target", default="native", choices=["native", "avx2"])
    parser.add_argument("--views", type=int, default=6)
    parser.add_argument("--threads", type=int, help="Dr.Jit's thread pool size (default: every core)")
    args = parser.parse_args()

    from agrisim.plugins.render.mitsuba.cpu import emulate_llvm_target, llvm_target
    from agrisim.plugins.render.mitsuba.variant import resolve_variant

    resolve_variant("llvm")  # points Dr.Jit at a libLLVM first
    if args.target == "avx2":
        emulate_llvm_target("avx2")
    import drjit as dr

    from agrisim.files import layout
    from agrisim.files.rundir import camera_from_json
    from agrisim.plugins.formats.scene_glb import read_scene
    from agrisim.plugins.render.raycast import RaycastOptions
    from agrisim.plugins.render.raycast.tracing import SceneTracer, label_map

    if args.threads:
        dr.set_thread_count(args.threads)
    cameras = json.loads((args.run_dir / "cameras.json").read_text())
    camera = camera_from_json(cameras["intrinsics"])
    frames = list(cameras["frames"])[: args.views]
    scene = read_scene(args.run_dir / layout.SCENE_GLB)
    tracer = SceneTracer(scene, None, RaycastOptions(variant="llvm"), arms=scene.arms)
    engine, mi = tracer.engine, tracer.mi
    lmap = label_map("organs")
    target = llvm_target()
    print(
        f"CPU: {cpu_model()}, {os.cpu_count()} cores; Dr.Jit compiles for {target.cpu}, "
        f"{target.width} lanes ({args.target}); {camera.width}x{camera.height}, "
        f"{sum(len(m.faces) for m in scene.meshes):,} static triangles, arms {sorted(scene.arms)}"
    )

    def poses(frame: str) -> dict:
        doc = json.loads(layout.link_poses(args.run_dir, frame).read_text())
        return {r: {k: np.asarray(T) for k, T in links.items()} for r, links in doc.items()}

    rows: dict[str, list[tuple[float, float, int]]] = {}

    @contextmanager
    def stage(name: str, keep: bool) -> Iterator[None]:
        """Time what the block evaluates: Dr.Jit's kernel times and the wall clock."""
        dr.kernel_history()
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            t0 = time.perf_counter()
            yield
            dr.sync_thread()
            wall = (time.perf_counter() - t0) * 1e3
            jit = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
        if keep:  # (the first view compiles)
            rows.setdefault(name, []).append((sum(k.get("execution_time", 0.0) for k in jit), wall, len(jit)))

    for i, frame in enumerate(frames):
        T = np.asarray(cameras["frames"][frame]["world_T_camera"], np.float64)
        keep = i > 0
        with stage("posing the arms (their acceleration structure rebuilt)", keep):
            tracer.place_arms(poses(frame), (camera, T))
            o, d = tracer.camera_rays(camera, T, rows=(0, 1))  # a row's cast: Embree builds lazily
            dr.eval(tracer.trace(o, d).t)
        with stage("camera rays", keep):
            o, d = tracer.camera_rays(camera, T)
            dr.eval(o, d)
        ray = mi.Ray3f(o, d / dr.norm(d))
        names = ["solid static scene (room, table, pot)", "walked static scene (the plant)", "arms in view"]
        for name, layer in zip(names, engine.layers, strict=True):
            with stage(f"one cast, {name}", keep):
                dr.eval(layer.scene.ray_intersect_preliminary(ray, coherent=True).t)
        with stage("the walk (the solid cast, then every layer of the plant: opacity and culling)", keep):
            s = tracer.trace(o, d)
            dr.eval(s.t, s.face, s.b)
        with stage("annotations (labels, instances, depth)", keep):
            annotated = [x for x in tracer.annotate(s, False, lmap) if x is not None]
            dr.eval(*annotated)
        with stage("copy to the host", keep):
            [np.asarray(x) for x in annotated]
        with stage("the exact pass, fused, to host memory", keep):
            tracer.exact(camera, T, seg_mode="texture", label_map=lmap)
    print("| stage | kernels | kernel ms | wall ms |")
    print("|---|---|---|---|")
    for name, values in rows.items():
        kernel_ms = statistics.median(v[0] for v in values)
        wall_ms = statistics.median(v[1] for v in values)
        print(f"| {name} | {values[0][2]} | {kernel_ms:.1f} | {wall_ms:.1f} |")
    tracer.close()


if __name__ == "__main__":
    main()
