"""What a neighbour hides: each plant of a small bench measured on the bench and alone, same seed,
same views. Prints a Markdown table (spacing, plant, the pixels of it its neighbours hide,
coverage and recall alone and on the bench, the loss) and the machine; asserts that a plant
nothing hides in any view loses nothing (a far one, unless a view of another plant's looks
across the bench at it from behind that plant).

    python bench/bench_crowding.py                              # gantry, 1x3 bench, 0.35 / 0.5 / 1.0 m
    python bench/bench_crowding.py --spacings 0.4,0.8 --resolution 320x240 --setpoints 2x4

"Alone" is the very bench run (the same rig, cell, pots, gantry tour, seeds, so the same camera
poses) with the scene's plant only plant k, grown alone from its seed (the run's plant seed plus
k - 1) and moved to its pot: only the neighbouring plants are gone, their pots stay. Both sides
are read from metrics.json's ``plants`` (each plant's own pixels against its own faces).

* coverage: the share of the plant's true surface samples any view sees (``truth_samples_seen``
  / ``truth_samples``): what the cameras could reconstruct at best;
* recall@d: the share of them within d of the plant's reconstructed cloud.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
from PIL import Image

import agrisim.episode
from agrisim.bench import join_plants
from agrisim.config import RunConfig, build_config
from agrisim.episode import Episode
from agrisim.plant_choice import bench_configs, resolve_plant
from agrisim.registry import Registry, make_plugin_manager


def run(config: RunConfig, only: int | None = None) -> dict[str, Any]:
    """The bench's run (with ``only``: the scene's plant that bench plant alone, 1-based);
    metrics.json's ``plants``."""
    if only is None:
        Episode(config).run()
    else:
        registry = Registry(make_plugin_manager())
        slot, alone = bench_configs(registry, config)[only - 1]
        plant = join_plants([resolve_plant(registry, alone)], [slot])
        # the episode grows its plant by resolve_plant: this one instead, all else the bench's
        with mock.patch.object(agrisim.episode, "resolve_plant", return_value=plant):
            Episode(config).run()
    assert config.output.out is not None
    return json.loads((Path(config.output.out) / "metrics.json").read_text())["plants"]


def hidden(bench: Path, alone: Path, k: int) -> int:
    """Pixels of the plant alone (its id 1 there) that on the bench (its id ``k``) show something
    else, over every view: what its neighbours hide of it."""
    out = 0
    for path in sorted((alone / "plants").glob("*.png")):
        mine = np.array(Image.open(path)) == 1
        out += int((mine & (np.array(Image.open(bench / "plants" / path.name)) != k)).sum())
    return out


def figures(row: dict[str, Any], t: str) -> tuple[float, float]:
    """(coverage, recall@t mm) of a plant's metrics."""
    label = row["labels"]["all"]
    return label["truth_samples_seen"] / label["truth_samples"], label["recall"][t]


def cpu() -> str:
    name = next(
        (
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if "model name" in line
        ),
        platform.processor(),
    )
    flags = Path("/proc/cpuinfo").read_text()
    isa = "AVX-512" if " avx512f" in flags else "AVX2" if " avx2" in flags else "SSE"
    cores = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    return f"{name}, {isa}, {cores} cores"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacings", default="0.35,0.5,1.0", help="pot spacings, m (the last: far apart)")
    parser.add_argument("--bench", default="1x3", help="the bench's grid, RxC")
    parser.add_argument("--setpoints", default="1x3", help="each plant's hemisphere, levels x azimuths")
    parser.add_argument("--resolution", default="160x120", help="WxH")
    parser.add_argument("--threshold", default="5", help="recall's threshold, mm (of metrics.thresholds_mm)")
    parser.add_argument("--out", type=Path, default=None, help="keep the runs here (default: a temporary folder)")
    args = parser.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="bench-crowding-"))
    rows = []
    t0 = time.perf_counter()
    for spacing in [float(s) for s in args.spacings.split(",")]:
        base = {
            "rig": {"backend": "gantry"},
            "bench": {"grid": args.bench, "spacing": spacing},
            "physics": {"backend": "kinematic"},
            "routine": {"setpoints": args.setpoints},
            "camera": {"resolution": args.resolution},
            "render": {"shadow_samples": 0},
            "output": {"no_rrd": True},
        }
        where = root / f"s{spacing:g}"
        bench = run(build_config(base, {"output": {"out": str(where / "bench")}}))
        for k, name in enumerate(bench, 1):
            alone = run(build_config(base, {"output": {"out": str(where / name)}}), only=k)[name]
            rows.append((spacing, name, bench[name], alone, hidden(where / "bench", where / name, k)))
    wall = time.perf_counter() - t0
    t = args.threshold
    print(
        "| spacing m | plant | views | px hidden | coverage alone | coverage bench | loss | "
        f"recall@{t}mm alone | on bench | loss |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for spacing, name, on, alone, px in rows:
        (ca, ra), (cb, rb) = figures(alone, t), figures(on, t)
        print(
            f"| {spacing:g} | {name} | {on['frames']} | {px} | {ca:.3f} | {cb:.3f} | {ca - cb:+.3f} | "
            f"{ra:.3f} | {rb:.3f} | {ra - rb:+.3f} |"
        )
    print(
        f"\n{len(rows)} plants on {len(rows) // len(set(r[0] for r in rows))}-plant benches, each alone too: "
        f"{wall:.0f} s wall on {cpu()}; runs in {root}"
    )
    for _, name, on, alone, px in rows:
        if px == 0:  # nothing of a neighbour in front of it in any view: the same as alone
            assert figures(on, t) == figures(alone, t), name
            assert on["labels"]["all"]["points"] == alone["labels"]["all"]["points"], name


if __name__ == "__main__":
    main()
