"""Several views in one launch (Mitsuba's ``batch`` sensor: K cameras side by side on one film)
against one launch a view, for the mitsuba renderer on a saved run's scene. Only views that see
the same scene can share a launch: the arms are left out (in a run they move between views).
Frozen renders, kernels timed after ``dr.eval`` and a sync. Prints figures; asserts nothing.

    python bench/mitsuba_batch.py RUN_DIR [--variant cuda] [--views 4] [--spp 8] [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402
from saved_run import saved_run  # noqa: E402

from agrisim.config import RenderConfig  # noqa: E402
from agrisim.plugins.render.mitsuba.camera import sensor_dict  # noqa: E402
from agrisim.plugins.render.mitsuba.options import MitsubaOptions  # noqa: E402
from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--views", type=int, default=4)
    parser.add_argument("--spp", type=int, default=MitsubaOptions().spp)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    import drjit as dr

    saved = saved_run(args.run_dir)
    cameras, camera = saved.cameras, saved.camera
    views = [np.asarray(cameras["frames"][f]["world_T_camera"]) for f in sorted(cameras["frames"])[: args.views]]
    options = MitsubaOptions(variant=args.variant, spp=args.spp, denoise="off", freeze="on")
    r = MitsubaRenderer(saved.scene, None, RenderConfig(hide_robots=True), options)
    mi = r.mi
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}; variant {mi.variant()}")

    def timed(render) -> float:  # noqa: ANN001
        best = float("inf")
        for k in range(args.repeat + 2):  # two recordings first (Dr.Jit records twice)
            dr.sync_thread()
            t0 = time.perf_counter()
            dr.eval(render(k))
            dr.sync_thread()
            if k >= 2:
                best = min(best, time.perf_counter() - t0)
        return best

    def singles(k: int) -> list:
        return [r._render("image", r._placed_sensor(camera, T), 1000 * k + i) for i, T in enumerate(views)]

    W, H = camera.width, camera.height
    batch = {
        "type": "batch",
        "film": {
            "type": "hdrfilm",
            "width": W * len(views),
            "height": H,
            "pixel_format": "rgb",
            "rfilter": {"type": "box"},
            "sample_border": False,
        },
        "sampler": {"type": options.sampler, "sample_count": args.spp},
    }
    for i, T in enumerate(views):
        d = sensor_dict(camera, T, args.spp, options.sampler)
        del d["film"], d["sampler"]
        d["to_world"] = mi.ScalarTransform4f(d["to_world"])
        batch[f"camera_{i}"] = d
    batched = mi.load_dict(batch)
    one = timed(singles)
    many = timed(lambda k: r._render("batch", batched, k))
    n = len(views)
    print(
        f"{W}x{H}, {n} views, {args.spp} spp, {options.integrator}: one launch a view {1e3 * one / n:.0f} ms a view; "
        f"one launch for all {1e3 * many / n:.0f} ms a view ({one / many:.2f}x)"
    )
    r.close()


if __name__ == "__main__":
    main()
