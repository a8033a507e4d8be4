"""Wall time of ``agrisim compare`` over the ten plants in both segmentation modes (the paper's
Table 2: 20 episodes as Ray tasks), with per-episode time and memory. Prints figures and the
table; asserts nothing.

    python bench/compare_plants.py                        # the paper's settings (long: 20 full episodes)
    python bench/compare_plants.py --quick                # 1x2 setpoints at 160x90: a check of the script
    python bench/compare_plants.py --setpoints 2x5 --resolution 960x540 --workers 2
    python bench/compare_plants.py --keep runs/bench-compare   # keep the output directory

Memory: every episode runs in a fresh Ray worker (``max_calls=1``), so the per-episode peak RSS
should not grow from the first episode to the last, nor the driver's RSS as records come in;
the script prints both series' first, last and largest values.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

QUICK = ["--physics", "kinematic", "--setpoints", "1x2", "--resolution", "160x90", "--shadow-samples", "0"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny episodes: " + " ".join(QUICK))
    parser.add_argument("--workers", type=int, default=None, help="episodes at a time (default: one per CPU)")
    parser.add_argument("--plants", default=None, help="comma-separated plants (default: the ten species)")
    parser.add_argument("--setpoints", default=None, help="LxC instead of the default 5x10")
    parser.add_argument("--resolution", default=None, help="WxH instead of 1920x1080")
    parser.add_argument("--physics", default=None, help="physics backend (default: pybullet)")
    parser.add_argument("--keep", type=Path, default=None, help="write the compare here and keep it")
    args = parser.parse_args()

    tmp = None
    if args.keep is None:
        tmp = tempfile.mkdtemp(prefix="agrisim-bench-compare-")
        out = Path(tmp) / "compare"
    else:
        out = args.keep
    cmd = [sys.executable, "-m", "agrisim", "compare", "--out", str(out), "--overwrite"]
    cmd += QUICK if args.quick else []
    for flag in ("workers", "plants", "setpoints", "resolution", "physics"):
        value = getattr(args, flag)
        if value is not None:
            cmd += [f"--{flag}", str(value)]
    try:
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, text=True)
        wall = time.perf_counter() - t0
        print(proc.stdout, end="")
        if not (out / "compare.json").is_file():
            sys.exit(f"compare failed (exit {proc.returncode}) before writing compare.json")
        report = json.loads((out / "compare.json").read_text())
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)

    episodes = sorted((e for e in report["episodes"] if "finished_s" in e), key=lambda e: e["finished_s"])
    ray = report.get("ray") or {}
    print()
    print(
        f"agrisim compare {' '.join(cmd[4:])}: {wall:.1f} s wall for {len(report['episodes'])} episodes "
        f"(exit {proc.returncode}, status {report['status']})"
    )
    print(
        f"  Ray: start {ray.get('startup_s', 0):.1f} s, shutdown {ray.get('shutdown_s', 0):.1f} s, "
        f"{ray.get('cluster_cpus')} CPUs, Ray {ray.get('ray')}"
    )
    if not episodes:
        return
    walls = [e["wall_s"] for e in episodes]
    print(
        f"  per episode (in its worker): mean {sum(walls) / len(walls):.1f} s, min {min(walls):.1f} s, "
        f"max {max(walls):.1f} s; imports {sum(e.get('import_s', 0) for e in episodes) / len(episodes):.1f} s each"
    )
    for name, key in (("episode peak RSS", "rss_peak_mb"), ("driver RSS", "driver_rss_mb")):
        series = [e[key] for e in episodes if e.get(key) is not None]
        if series:
            print(
                f"  {name} (MB, in finishing order): first {series[0]:.0f}, last {series[-1]:.0f}, "
                f"max {max(series):.0f}, min {min(series):.0f}"
            )
    print(f"  {'plant':<18} {'mode':<8} {'wall s':>7} {'peak MB':>8} {'pid':>7}")
    for e in episodes:
        peak = e.get("rss_peak_mb") or 0
        print(f"  {e['plant']:<18} {e['seg_mode']:<8} {e['wall_s']:>7.1f} {peak:>8.0f} {e.get('pid', 0):>7}")


if __name__ == "__main__":
    main()
