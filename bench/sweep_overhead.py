"""What ``agrisim sweep`` costs beyond its runs: the same grid run as a sweep and as plain
``agrisim run`` commands, ``--workers`` at a time either way, whole wall times side by side.
Prints figures; asserts nothing.

    python bench/sweep_overhead.py [--cells 4] [--workers 1 2] [--setpoints 2x4] [--resolution 640x360]

The grid is ``pcg_seed`` 1..N over a small kinematic raycast run (examples/sweeps' base). The
plain runs are one ``agrisim run --config BASE --set pcg_seed=K`` process each, started by a
pool of ``--workers`` threads: what a user would script without a sweep. The sweep adds Ray's
start, a fresh worker per run, the manifest and the progress polling; its runs are the same.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from agrisim.plugins.render.mitsuba.cpu import cpu_model, vector_isa


def agrisim(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "agrisim", *args], check=True, capture_output=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=4)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--setpoints", default="2x4")
    parser.add_argument("--resolution", default="640x360")
    args = parser.parse_args()
    print(f"CPU: {cpu_model()} ({vector_isa()}), {os.cpu_count()} cores")
    root = Path(tempfile.mkdtemp(prefix="sweep-overhead-"))
    base = (
        'physics.backend = "kinematic"\n'
        f'routine.setpoints = "{args.setpoints}"\ncamera.resolution = "{args.resolution}"\n'
        'output.no_rrd = true\nrecon.backend = "none"\n'
    )
    (root / "base.toml").write_text(base)
    seeds = list(range(1, args.cells + 1))
    (root / "spec.toml").write_text(base + f"[axes]\npcg_seed = {seeds}\n")
    agrisim("run", "--config", str(root / "base.toml"), "--out", str(root / "warm"))  # caches (leaf optics...)
    print(f"{args.cells} runs of {args.setpoints} setpoints at {args.resolution} (raycast, kinematic, no recon)")
    print("| workers | runs alone, s | sweep, s | overhead, s | overhead a run, s |")
    print("|---|---|---|---|---|")
    for workers in args.workers:
        t0 = time.perf_counter()
        with ThreadPoolExecutor(workers) as pool:
            jobs = [
                pool.submit(
                    agrisim,
                    "run",
                    "--config",
                    str(root / "base.toml"),
                    "--set",
                    f"pcg_seed={k}",
                    "--out",
                    str(root / f"plain-{workers}" / str(k)),
                )  # fmt: skip
                for k in seeds
            ]
            for job in jobs:
                job.result()
        alone = time.perf_counter() - t0
        t0 = time.perf_counter()
        agrisim("sweep", str(root / "spec.toml"), "--out", str(root / f"sweep-{workers}"), "--workers", str(workers))
        swept = time.perf_counter() - t0
        over = swept - alone
        print(f"| {workers} | {alone:.1f} | {swept:.1f} | {over:+.1f} | {over / args.cells:+.2f} |", flush=True)
    shutil.rmtree(root)


if __name__ == "__main__":
    main()
