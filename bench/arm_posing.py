"""Milliseconds to pose the arms (16 links) beside static scenes of 200, 20,000 and 320,000
triangles: flat when posing never rebuilds the static scene's acceleration structure. Prints
figures; asserts nothing. Works from a minimal install (agrisim's core, numpy, pydantic,
pluggy, Mitsuba and Dr.Jit), so it runs on the GPU machine too.

    python bench/arm_posing.py [--variant auto|llvm|cuda]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model, gpu_name  # noqa: E402

from agrisim.scene.model import LabelTable, Material, Mesh, Scene  # noqa: E402


def grid(n: int) -> Mesh:
    """A wavy n x n quad grid of 2 n^2 triangles over the unit square."""
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    v = np.column_stack([x.ravel(), y.ravel(), 0.01 * np.sin(20 * x.ravel())])
    i = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :n].ravel()
    f = np.concatenate([np.column_stack([i, i + 1, i + n + 2]), np.column_stack([i, i + n + 2, i + n + 1])])
    return Mesh("grid", v, f, [Material("m")], np.zeros(len(f), np.int32))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="auto", choices=["auto", "llvm", "cuda"])
    parser.add_argument("--grids", type=int, nargs="+", default=[10, 100, 400], help="static grids of 2 n^2 triangles")
    args = parser.parse_args()
    import drjit as dr

    from agrisim.plugins.render.mitsuba.variant import use_variant
    from agrisim.plugins.render.raycast.engine import Engine

    mi = use_variant(args.variant)
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}; variant {mi.variant()}")
    box = grid(4)
    links = [
        (f"l{i}", Mesh(f"l{i}", box.vertices, box.faces, [Material("a")], np.zeros(len(box.faces), np.int32)))
        for i in range(16)
    ]
    for n in args.grids:
        static = grid(n)
        engine = Engine(mi, Scene([static], [], LabelTable()), {"arm": links})
        times = []
        for k in range(16):
            T = np.eye(4)
            T[0, 3] = 3.0 + k  # a new pose every time: nothing is cached
            t0 = time.perf_counter()
            engine.place_arms({"arm": {f"l{i}": T for i in range(16)}})
            dr.sync_thread()
            times.append(time.perf_counter() - t0)
        print(
            f"  {len(static.faces):>7,} static triangles: posing 16 links {1e3 * np.median(times[1:]):.1f} ms (median of 15)"
        )


if __name__ == "__main__":
    main()
