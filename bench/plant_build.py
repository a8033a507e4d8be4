"""Seconds to build each procedural species (mesh, textures, labels), the median of a few
builds per species. Prints the CPU model and figures; asserts nothing.

    python bench/plant_build.py [--repeats 3] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import time

from machine import cpu_model  # bench/machine.py: the script's own folder is on sys.path

from agrisim.plugins.plants.procedural import grow
from agrisim.plugins.plants.procedural.species import SPECIES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(cpu_model())
    for name in SPECIES:
        seconds = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            plant = grow(name, args.seed)
            seconds.append(time.perf_counter() - t0)
        print(f"{name:18s} {statistics.median(seconds):6.3f} s   {len(plant.mesh.faces):7,d} triangles")


if __name__ == "__main__":
    main()
