"""Views per second of ``agrisim render`` (the mitsuba renderer re-rendering a saved run), as a
user runs it, for several sample counts. Prints figures; asserts nothing.

The first frame of each pass compiles Mitsuba's kernels and is reported apart; the rate is over
the frames after it. Works from a minimal install (agrisim's core, numpy, Pillow, pydantic,
pluggy, Mitsuba): this is how it is measured on the GPU machine.

    python bench/rerender_speed.py RUN_DIR [--spp 16 64 256] [--integrator path volpath] [--variant auto]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402

from agrisim.plugins.apps.render import RenderPlan  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--spp", type=int, nargs="+", default=[16, 64, 256])
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--denoise", default="auto")
    parser.add_argument("--integrator", nargs="+", default=["volpath"], choices=["cutout_path", "path", "volpath"])
    args = parser.parse_args()
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}")
    for integrator, spp in ((i, s) for i in args.integrator for s in args.spp):
        stamps: list[float] = []
        mitsuba = {"spp": spp, "variant": args.variant, "denoise": args.denoise, "integrator": integrator}
        options = {"renderer": {"mitsuba": mitsuba}}
        with tempfile.TemporaryDirectory() as tmp:
            plan = RenderPlan(args.run_dir, "mitsuba", options, Path(tmp) / "out", overwrite=False)
            t0 = time.perf_counter()
            plan.run(lambda done, total, stamps=stamps: stamps.append(time.perf_counter()))
            import mitsuba

            variant = mitsuba.variant()
        first = stamps[0] - t0
        rest = len(stamps) - 1
        rate = rest / (stamps[-1] - stamps[0]) if rest else float("nan")
        camera = plan.cameras["intrinsics"]
        print(
            f"{camera['width']}x{camera['height']}, {integrator}, {spp} spp, variant {variant}, denoise {args.denoise}: "
            f"first frame (scene load + kernel compile) {first:.1f} s, then {rate:.2f} views/s over {rest} frames"
        )


if __name__ == "__main__":
    main()
