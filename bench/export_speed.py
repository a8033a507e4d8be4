"""Time and size of the dataset exports for one run (the default: 100 views at 1080p): the COCO
annotations, the ROS 2 bag, and float depth as EXR beside the millimetre PNGs. Prints figures
with the CPU model; asserts nothing.

    python bench/export_speed.py [RUN_DIR]   # without RUN_DIR: makes the default run first
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model  # noqa: E402

from agrisim.config import build_config  # noqa: E402
from agrisim.episode import Episode  # noqa: E402
from agrisim.plugins.exporters.coco import COCO_JSON, write_coco  # noqa: E402
from agrisim.plugins.exporters.rosbag import write_rosbag  # noqa: E402


def size_mb(paths: list[Path]) -> float:
    return sum(p.stat().st_size for p in paths) / 1e6


def main() -> None:
    if len(sys.argv) > 1:
        run_dir = Path(sys.argv[1])
    else:
        run_dir = Path(tempfile.mkdtemp()) / "run"
        config = {
            "render": {"labels": "organs", "depth_format": "both"},
            "physics": {"backend": "kinematic"},
            "output": {"out": str(run_dir), "no_rrd": True},
        }
        t = time.perf_counter()
        Episode(build_config(config)).run()
        print(f"default run (indian cress, organs, 100 views at 1080p, depth as both): {time.perf_counter() - t:.1f} s")
    t = time.perf_counter()
    write_coco(run_dir, overwrite=True)
    seconds = time.perf_counter() - t
    frames = sorted((run_dir / "rgb").glob("*.png"))
    print(f"CPU: {cpu_model()}")
    print(f"agrisim export coco: {seconds:.1f} s for {len(frames)} frames, {size_mb([run_dir / COCO_JSON]):.1f} MB")
    t = time.perf_counter()
    bag = write_rosbag(run_dir, overwrite=True)
    seconds = time.perf_counter() - t
    images = size_mb(
        sorted((run_dir / "rgb").glob("*.png"))
        + sorted((run_dir / "labels").glob("*.png"))
        + sorted((run_dir / "depth").glob("*.png"))
    )
    print(
        f"agrisim export rosbag: {seconds:.1f} s, {size_mb(sorted(bag.iterdir())):.0f} MB "
        f"(the run's rgb, labels and depth PNGs: {images:.0f} MB)"
    )
    png, exr = sorted((run_dir / "depth").glob("*.png")), sorted((run_dir / "depth").glob("*.exr"))
    print(f"depth: {len(png)} PNGs {size_mb(png):.1f} MB, {len(exr)} EXRs {size_mb(exr):.1f} MB")


if __name__ == "__main__":
    main()
