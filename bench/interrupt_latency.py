"""Seconds from Ctrl-C (SIGINT) to the process's exit, for a run rendering at 1080p: how long a
user waits after pressing it. Each repeat starts `agrisim run` in a subprocess, waits until two
frames are complete, sends SIGINT and times the exit (status 130). Prints the CPU model and
figures; asserts nothing.

    python bench/interrupt_latency.py [--repeats 3] [--resolution 1920x1080]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import cpu_model  # bench/machine.py: the script's own folder is on sys.path


def frames_complete(out: Path) -> int:
    try:
        return len(json.loads((out / "run.json").read_text()).get("frames_complete") or [])
    except (OSError, ValueError):
        return 0


def one(resolution: str, root: Path) -> float:
    out = root / "run"
    cmd = [
        sys.executable,
        "-m",
        "agrisim",
        "run",
        "--physics",
        "kinematic",
        "--setpoints",
        "2x5",
        "--resolution",
        resolution,
        "--no-rrd",
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env={**os.environ})
    while frames_complete(out) < 2:
        if proc.poll() is not None:
            raise SystemExit(f"the run exited early: {proc.stderr.read().decode() if proc.stderr else ''}")
        time.sleep(0.01)
    sent = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    proc.wait()
    took = time.perf_counter() - sent
    if proc.returncode != 130:
        raise SystemExit(f"expected exit status 130, got {proc.returncode}")
    return took


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--resolution", default="1920x1080")
    args = parser.parse_args()
    print(cpu_model())
    times = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as tmp:
            times.append(one(args.resolution, Path(tmp)))
    print(
        f"SIGINT to exit at {args.resolution}: median {statistics.median(times):.2f} s, "
        f"max {max(times):.2f} s over {len(times)} runs"
    )


if __name__ == "__main__":
    main()
