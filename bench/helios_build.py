"""Seconds to grow a Helios plant and convert it into agrisim's plant asset (default: a 40-day
tomato), split into Helios's growth, reading the primitives, organs and instances, and building
the mesh with its textures. Prints figures; asserts nothing.

    python bench/helios_build.py [--model tomato] [--age 40] [--seed 0] [--repeats 3]

Needs the optional extra: ``pip install agrisim[helios]``.
"""

from __future__ import annotations

import argparse
import statistics
import time

from agrisim.plugins.plants.helios import HeliosPlantOptions, grow, helios_plant
from agrisim.plugins.plants.helios import convert as hc


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="tomato")
    parser.add_argument("--age", type=float, default=40.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    stages: dict[str, list[float]] = {"grow": [], "fetch": [], "organs": [], "mesh": []}
    totals: list[float] = []
    for k in range(args.repeats):
        hc._texture.cache_clear()  # every repeat reads its textures, as a fresh process does
        t0 = time.perf_counter()
        with helios_plant(args.model, args.age, args.seed) as (ctx, pa, plant_id):
            t1 = time.perf_counter()
            prims = hc.fetch(ctx, ctx.getAllUUIDs())
            t2 = time.perf_counter()
            labels, instances = hc.organ_labels(pa, ctx, plant_id, prims)
            t3 = time.perf_counter()
            mesh = hc.to_mesh(ctx, prims, labels, instances, f"helios:{args.model}")
            t4 = time.perf_counter()
        for name, dt in zip(stages, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True):
            stages[name].append(dt)
        # the whole public path (grow + convert + fit), as `agrisim run --plant helios:...` calls it
        hc._texture.cache_clear()
        t5 = time.perf_counter()
        plant = grow(args.model, args.seed, HeliosPlantOptions(age=args.age))
        totals.append(time.perf_counter() - t5)
        if k == 0:
            n_leaves = len(set(mesh.face_instance.tolist()) - {0})
            organs = ", ".join(lab.name for lab in plant.labels.labels if lab.id)
            print(
                f"helios:{args.model} at {args.age:g} days, seed {args.seed}: {len(prims):,} Helios primitives -> "
                f"{len(mesh.faces):,} triangles, {len(mesh.materials)} materials, {n_leaves} leaf instances; {organs}"
            )
            for note in plant.notes:
                print(f"  note: {note}")
    split = ", ".join(f"{name} {statistics.median(v):.2f} s" for name, v in stages.items())
    print(f"  median of {args.repeats}: {split}")
    median, worst = statistics.median(totals), max(totals)
    print(f"  build + convert (grow()): median {median:.2f} s, max {worst:.2f} s (target < 5 s)")


if __name__ == "__main__":
    main()
