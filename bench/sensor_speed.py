"""A view's cost with a depth sensor against the renderer's alone, in one run: a saved run's
frames re-measured with each sensor and re-rendered with ``raycast`` (its defaults), medians
after the first view (which compiles). Prints figures; asserts nothing.

    python bench/sensor_speed.py RUN_DIR [--sensors azure-kinect-nfov] [--views 6] [--variant llvm]

The sensor's time is split into its own rays (traced on Dr.Jit at its native resolution), the
physics on the host (mixing, noise, invalidation) and the alignment to the colour camera.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--sensors", default="azure-kinect-nfov")
    parser.add_argument("--views", type=int, default=6)
    parser.add_argument("--variant", default="llvm", choices=["llvm", "cuda"])
    args = parser.parse_args()

    from agrisim.config import RenderConfig
    from agrisim.files import layout
    from agrisim.files.rundir import camera_from_json
    from agrisim.plugins.formats.scene_glb import read_scene
    from agrisim.plugins.render.raycast import RaycastOptions
    from agrisim.plugins.render.raycast.renderer import RaycastRenderer
    from agrisim.plugins.sensors.align import align_to_colour
    from agrisim.registry import Registry, make_plugin_manager

    cameras = json.loads((args.run_dir / "cameras.json").read_text())
    camera = camera_from_json(cameras["intrinsics"])
    frames = list(cameras["frames"])[: args.views]
    scene = read_scene(args.run_dir / layout.SCENE_GLB)
    settings = RenderConfig()
    where = cpu_model() if args.variant == "llvm" else gpu_name()
    print(f"{where}; {camera.width}x{camera.height} colour, {len(frames)} views, variant {args.variant}")

    def poses(frame: str) -> dict:
        doc = json.loads(layout.link_poses(args.run_dir, frame).read_text())
        return {r: {k: np.asarray(T) for k, T in links.items()} for r, links in doc.items()}

    views = [(np.asarray(cameras["frames"][f]["world_T_camera"], np.float64), poses(f)) for f in frames]
    renderer = RaycastRenderer(scene, None, settings, RaycastOptions(variant=args.variant))
    times = []
    for T, p in views:
        t0 = time.perf_counter()
        frame = renderer.render(camera, T, p)
        times.append(time.perf_counter() - t0)
    base = statistics.median(times[1:])
    print(f"  raycast view (RGB, labels, depth; 1 shadow sample): {base:.3f} s")

    registry = Registry(make_plugin_manager())
    for name in args.sensors.split(","):
        spec = registry.get("sensor", name)
        sensor = registry.build("sensor", spec, scene, None, settings, spec.options_model(variant=args.variant))
        rows = []
        for T, p in views:
            t0 = time.perf_counter()
            native = sensor.measure_native(T, p, 0)
            t1 = time.perf_counter()
            align_to_colour(native, sensor.camera, camera, sensor.camera_T_sensor)
            rows.append((t1 - t0, time.perf_counter() - t1))
        native_s = statistics.median(r[0] for r in rows[1:])
        align_s = statistics.median(r[1] for r in rows[1:])
        total = native_s + align_s
        print(
            f"  {name}: {total:.3f} s a view ({native_s:.3f} s at its {sensor.camera.width}x{sensor.camera.height}, "
            f"{align_s:.3f} s aligning) = {total / base:.2f}x the raycast view"
        )
        sensor.close()
    del frame
    renderer.close()


if __name__ == "__main__":
    main()
