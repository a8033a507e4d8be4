"""Each plant and seed's 100 candidate looks, taken once and kept on disk, so that replaying
policies on them (``bench/nextview_replay.py --cache``), or fitting a gain to them, costs no
rendering.

A plant and seed is grown as ``agrisim nextview`` grows it (``env.reset(seed=s, options=
{"plant_seed": s, "pcg_seed": 42})``) and looked at from every candidate with the arms left out
(``env.look_from``). Its file, ``CACHE/<plant>_s<seed>_<W>x<H>.npz``, keeps:

- the candidates' poses and arms, the arms' cameras at the start, the camera's intrinsics, the
  voxel map's centre and size: all a replay needs to stand in for the environment;
- each look's depth and labels at the pixels :meth:`VoxelMap.integrate` reads (every 4th row
  and column from the 2nd, and each one's right and lower neighbour, which its normals use):
  the map fused from the cache is the map fused from the full images, voxel for voxel;
- each look's true visibility, ``env.coverage.visible(view)`` on an empty coverage (the truth's
  samples it sees and from which side), the truth's sheet mask and labels: the coverage a
  replay counts is the environment's.

    python bench/nextview_cache.py --cache ~/nv-cache --plant all --seeds 5 [--resolution 480x270]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.plugins.apps.nextview.env import PlantViewEnv

#: the ten procedural species of the benchmark (``agrisim plants``, not the helios crops)
SPECIES = (
    "amaryllis",
    "basket_grass",
    "bog_marshcress",
    "boston_fern",
    "boxwood",
    "chinese_evergreen",
    "coltsfoot",
    "common_fern",
    "hydrangea",
    "indian_cress",
)
#: the pixel stride of ``VoxelMap.integrate``'s default
STRIDE = 4


def cache_path(cache: Path, plant: str, seed: int, resolution: str) -> Path:
    """Where one plant and seed's looks are kept."""
    return Path(cache) / f"{plant}_s{seed}_{resolution}.npz"


def pixels(size: int, stride: int = STRIDE) -> np.ndarray:
    """The rows (or columns) of an image ``size`` long that ``integrate`` reads: its samples
    and each one's next (or, at the edge, previous) neighbour."""
    samples = np.arange(stride // 2, size, stride)
    return np.unique(np.concatenate([samples, np.where(samples + 1 < size, samples + 1, samples - 1)]))


def build(plant: str, seed: int, resolution: str) -> dict[str, Any]:
    """One plant and seed's cache record (see the module)."""
    env = PlantViewEnv(plant=plant, resolution=resolution)
    env.reset(seed=seed, options={"plant_seed": seed, "pcg_seed": 42})
    cam = env.camera
    assert cam.distortion is None, "the cache keeps a pinhole's intrinsics only"
    rows, cols = pixels(cam.height), pixels(cam.width)
    depth, labels, vis_idx, vis_side, offsets = [], [], [], [], [0]
    for sp in env.candidates:
        view = env.look_from(sp.world_T_camera)
        d, lab = np.asarray(view.images.depth, np.float32), np.asarray(view.images.labels, np.uint8)
        depth.append(d[np.ix_(rows, cols)])
        labels.append(lab[np.ix_(rows, cols)])
        seen, side = env.coverage.visible(view)  # the env's coverage is empty: all it sees
        vis_idx.append(seen.astype(np.int32))
        vis_side.append(side.astype(np.uint8))
        offsets.append(offsets[-1] + len(seen))
    truth = env.coverage.truth
    record = {
        "plant": np.array(plant),
        "seed": np.array(seed),
        "resolution": np.array(resolution),
        "poses": np.stack([sp.world_T_camera for sp in env.candidates]),
        "robots": np.array([sp.robot for sp in env.candidates]),
        "arms": np.array(env.arms),
        "arm_cameras": np.stack([env.camera_position(a) for a in env.arms]),
        "intrinsics": np.array([cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy], np.float64),
        "centre": np.asarray(env._centre, np.float64),
        "grid": np.array(env._grid, np.float64),  # cells, size_m
        "rows": rows,
        "cols": cols,
        "depth": np.stack(depth),
        "labels": np.stack(labels),
        "vis_idx": np.concatenate(vis_idx),
        "vis_side": np.concatenate(vis_side),
        "vis_off": np.array(offsets, np.int64),
        "sheet": env.coverage.sheet,
        "truth_labels": np.asarray(truth.labels, np.uint8),
    }
    env.close()
    return record


def full_images(record: Any, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Look ``i``'s depth and labels as full images, zero where the cache kept nothing
    (pixels ``integrate`` never reads)."""
    w, h = (int(x) for x in record["intrinsics"][:2])
    rows, cols = record["rows"], record["cols"]
    depth, labels = np.zeros((h, w), np.float32), np.zeros((h, w), np.uint8)
    depth[np.ix_(rows, cols)] = record["depth"][i]
    labels[np.ix_(rows, cols)] = record["labels"][i]
    return depth, labels


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cache", type=Path, required=True)
    parser.add_argument("--plant", nargs="+", default=["all"])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--resolution", default="480x270")
    args = parser.parse_args()
    plants = list(SPECIES) if args.plant == ["all"] else args.plant
    args.cache.mkdir(parents=True, exist_ok=True)
    # seeds outer: the first seeds of every species first, so a partial cache already spans them
    for seed in range(args.seeds):
        for plant in plants:
            path = cache_path(args.cache, plant, seed, args.resolution)
            if path.exists():
                continue
            t0 = time.perf_counter()
            record = build(plant, seed, args.resolution)
            tmp = path.with_suffix(".tmp.npz")
            np.savez_compressed(tmp, **record)
            tmp.rename(path)
            print(
                f"{plant} seed {seed}: {time.perf_counter() - t0:.1f} s, {path.stat().st_size / 1e6:.1f} MB", flush=True
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
