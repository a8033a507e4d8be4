"""Memory stays flat: peak RSS of the default ``agrisim run`` (100 views at 1080p, recording and
reconstruction included), then the RSS of one process after each of ten consecutive episodes.
Prints figures; asserts nothing.

    python bench/memory.py                       # default run + ten episodes at 960x540
    python bench/memory.py --skip-default        # only the ten episodes
    python bench/memory.py --resolution 320x180  # a quick check of the script
"""

from __future__ import annotations

import argparse
import gc
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def rss_mb() -> float:
    """Resident set size of this process now, MB (Linux)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-default", action="store_true", help="skip the full default run")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--resolution", default="960x540", help="of the consecutive episodes")
    parser.add_argument("--setpoints", default="2x5", help="of the consecutive episodes")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        if not args.skip_default:
            t0 = time.perf_counter()
            cmd = [sys.executable, "-m", "agrisim", "run", "--out", str(Path(tmp) / "default")]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
            print(
                f"default run (100 views at 1920x1080, recording + reconstruction): peak RSS {peak:,.0f} MB, "
                f"{time.perf_counter() - t0:.0f} s"
            )

        from agrisim.config import build_config
        from agrisim.episode import Episode

        plants = ["indian_cress", "boston_fern", "hydrangea", "coltsfoot", "basket_grass"]
        print(
            f"{args.episodes} consecutive episodes in one process ({args.setpoints} setpoints per arm, {args.resolution}):"
        )
        start = rss_mb()
        for i in range(args.episodes):
            config = build_config(
                {
                    "plant": plants[i % len(plants)],
                    "render": {"seg_mode": "texture" if i % 2 == 0 else "repopa"},
                    "routine": {"setpoints": args.setpoints},
                    "camera": {"resolution": args.resolution},
                    "output": {"out": str(Path(tmp) / f"episode{i}")},
                }
            )
            t0 = time.perf_counter()
            Episode(config).run()
            gc.collect()
            print(
                f"  episode {i + 1:2d} ({config.plant}, {config.render.seg_mode}): RSS {rss_mb():,.0f} MB "
                f"({time.perf_counter() - t0:.0f} s)"
            )
        print(f"  RSS grew {rss_mb() - start:+,.0f} MB over the episodes (from {start:,.0f} MB before the first)")


if __name__ == "__main__":
    main()
