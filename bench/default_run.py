"""Wall time and peak memory of the full default ``agrisim run`` (100 views at 1080p, pybullet
physics, OMPL, raycast renderer, dataset files and Rerun recording). Prints figures; asserts
nothing.

    python bench/default_run.py                 # the default run (about two minutes)
    python bench/default_run.py --setpoints 1x2 # a quick check of the script
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setpoints", default=None, help="LxC instead of the default 5x10")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "agrisim", "run", "--out", str(out)]
        if args.setpoints:
            cmd += ["--setpoints", args.setpoints]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        run = json.loads((out / "run.json").read_text())
        rrd_mb = (out / "recording.rrd").stat().st_size / 1e6
        data_mb = sum(f.stat().st_size for f in out.rglob("*.png")) / 1e6
    s = run["summary"]
    stages = ", ".join(f"{k} {v:.1f}" for k, v in s["wall_s"].items())
    frames = len(run["frames_complete"])
    what = f"--setpoints {args.setpoints}" if args.setpoints else "(defaults)"
    print(
        f"agrisim run {what}: {wall:.1f} s wall, "
        f"{frames} frames ({wall / max(frames, 1):.2f} s per frame), peak RSS {peak_mb:.0f} MB"
    )
    print(f"  reached {s['reached']}/{s['setpoints']}, collisions {s['collisions']}; stages (s): {stages}")
    print(f"  images on disk {data_mb:.0f} MB, recording {rrd_mb:.0f} MB")


if __name__ == "__main__":
    main()
