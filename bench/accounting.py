"""Where the seconds of an ``agrisim run`` go: the run's own stage clocks (wall time) and a
sampling profile of every Python thread (py-spy, native frames included), sorted into the
categories below. Prints figures; asserts nothing.

    python bench/accounting.py                      # the default run (about two minutes)
    python bench/accounting.py --setpoints 2x5      # ten views: a quicker look
    python bench/accounting.py -- --renderer none   # arguments after -- go to agrisim run

Reading it: *wall* is the stage clocks of ``run.json`` (the main thread's timeline; start-up is
the process's wall time less the stages). *Thread-seconds* are profiler samples divided by the
rate, summed over Python threads: the renderer's tile threads and the dataset writer run beside
the main thread, so they can add up to more than the wall time. Samples where a thread waits for
the GIL are counted apart; idle waits are dropped. Threads that are not Python's (Embree's TBB
workers, Rerun's encoder and file writer) are not sampled: their CPU time is the process's CPU
time (``getrusage``) less the sampled CPU time, printed as *native threads*.
"""

from __future__ import annotations

import argparse
import json
import linecache
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

#: (category, test on one frame of the stack) tried from the innermost frame outwards; the
#: first frame that matches any rule decides. Native frames come before Python ones.
RULES: list[tuple[str, re.Pattern[str]]] = [
    (
        "render: Dr.Jit kernels (ray casts, walks, shading)",
        re.compile(r"embree|nanothread|drjit|libdrjit|jit_llvm|jitc_", re.I),
    ),
    ("PNG encoding", re.compile(r"ImagingZip|PngImagePlugin|ZipEncode|write_png|encode_png|isal")),
    ("render: posing the arms (BVH build)", re.compile(r"Engine\.place_arms|SceneTracer\.place_arms")),
    (
        "render: building a view's kernels (Python)",
        re.compile(r"Engine\.|SceneTracer\.|Shader\.|MaterialArrays\.|RaycastRenderer\."),
    ),
    ("depth to millimetres", re.compile(r"depth_to_mm")),
    ("Rerun logging (Python side)", re.compile(r"rerun_sink|/rerun/|rerun_bindings")),
    ("run.json, cameras.json, trajectories", re.compile(r"write_json|_write_pretty|json_text|_run_json|json/encoder")),
    ("IK", re.compile(r"ArmKinematics\.(ik|_solve|nearest_equivalent)")),
    ("collision queries", re.compile(r"arms_in_collision|in_collision|_World\.near|segment_is_valid|Episode\._valid")),
    ("planning (OMPL)", re.compile(r"Planner\.plan|ompl", re.I)),
    ("trajectory (Ruckig)", re.compile(r"time_parametrize|ruckig", re.I)),
    ("physics stepping", re.compile(r"BulletPhysics\.execute|stepSimulation")),
    ("physics set-up", re.compile(r"BulletPhysics\.__init__|_World\.__init__")),
    ("reconstruction", re.compile(r"/recon/|write_reconstruction|backproject")),
    ("metrics", re.compile(r"evaluation/metrics|SurfaceDistance|GroundTruth")),
    (
        "scene and plant building",
        re.compile(r"build_scene|resolve_plant|build_cell|arm_link_meshes|export_glb|write_scene"),
    ),
    ("imports", re.compile(r"importlib\._bootstrap|<module>")),
]
#: a thread blocked here is idle, not working
IDLE = re.compile(
    r"Condition\.wait|_queue_SimpleQueue_get|PyThread_acquire_lock_timed|Thread\.join|epoll_wait|select \(|sleep"
)
#: the innermost native frame of a thread waiting for the GIL (CPython's take_gil, inlined)
GIL_WAIT = re.compile(r"pthread_cond_timedwait|take_gil")


def classify(frames: list[str]) -> str:
    """The category of one sampled stack (outermost frame first)."""
    tail = frames[-6:]
    if any(IDLE.search(f) for f in tail[-3:]):
        return "idle"
    if any(GIL_WAIT.search(f) for f in tail[-2:]):
        return "waiting for the GIL"
    for frame in reversed(frames):
        for name, rule in RULES:
            if rule.search(frame):
                return name
    return "other"


def thread_kind(name: str) -> str:
    if "MainThread" in name:
        return "main"
    if "agrisim-dataset" in name:
        return "dataset writer"
    if "ThreadPoolExecutor" in name:
        return "render tiles"
    return "other threads"


def profile(cmd: list[str], rate: int, out_raw: Path) -> tuple[float, float]:
    """Run ``cmd`` under py-spy; (wall s, CPU s of the process and its children)."""
    spy = shutil.which("py-spy") or str(Path(sys.executable).with_name("py-spy"))
    t0 = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(
        [spy, "record", "--native", "--threads", "-r", str(rate), "-f", "raw", "-o", str(out_raw), "--", *cmd],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setpoints", default=None, help="LxC instead of the default 5x10")
    parser.add_argument("--rate", type=int, default=50, help="samples per second and thread")
    parser.add_argument("--top", type=int, default=0, help="also print the N busiest Python lines")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")
    parser.add_argument("extra", nargs="*", help="more arguments for agrisim run (after --)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "agrisim", "run", "--out", str(out), *args.extra]
        if args.setpoints:
            cmd += ["--setpoints", args.setpoints]
        raw = Path(tmp) / "profile.txt"
        wall, cpu = profile(cmd, args.rate, raw)
        run = json.loads((out / "run.json").read_text())
        rrd = out / "recording.rrd"
        rrd_mb = rrd.stat().st_size / 1e6 if rrd.exists() else 0.0
        samples = [line.rstrip().rsplit(" ", 1) for line in raw.read_text().splitlines() if line.strip()]

    by_cat: Counter[str] = Counter()
    by_thread: dict[str, Counter[str]] = {}
    lines: Counter[str] = Counter()
    for stack, n in samples:
        frames = stack.split(";")
        kind = thread_kind(frames[0])
        cat = classify(frames)
        by_thread.setdefault(kind, Counter())[cat] += int(n)
        by_cat[cat] += int(n)
        py = [f for f in frames if re.search(r"\.py:\d+\)$", f)]
        if cat not in ("idle", "waiting for the GIL") and py:
            lines[py[-1]] += int(n)
    rate = float(args.rate)
    stages = run["summary"]["wall_s"]
    frames_done = len(run["frames_complete"])
    what = " ".join(args.extra + (["--setpoints", args.setpoints] if args.setpoints else [])) or "(defaults)"
    print(f"agrisim run {what} on {cpu_model()} ({frames_done} frames)")
    print(f"  process: {wall:.1f} s wall under the profiler, {cpu:.1f} s CPU; recording {rrd_mb:.0f} MB")
    staged = sum(stages.values())
    print("  wall time by stage (run.json):")
    for name, s in sorted(stages.items(), key=lambda kv: -kv[1]):
        print(f"    {name:14s} {s:7.1f} s")
    print(f"    {'start-up, end':14s} {wall - staged:7.1f} s  (process wall less the stages)")
    busy = {k: v for k, v in by_cat.items() if k not in ("idle",)}
    sampled_cpu = sum(v for k, v in busy.items() if k != "waiting for the GIL") / rate
    print("  thread-seconds by category (py-spy, all Python threads):")
    for name, n in sorted(busy.items(), key=lambda kv: -kv[1]):
        kinds = ", ".join(f"{k} {c[name] / rate:.1f}" for k, c in sorted(by_thread.items()) if c[name])
        print(f"    {name:40s} {n / rate:7.1f} s  ({kinds})")
    print(
        f"    {'native threads (TBB, Rerun), unsampled':40s} {max(cpu - sampled_cpu, 0.0):7.1f} s  (process CPU less sampled CPU)"
    )
    if args.top:
        print("  busiest Python lines (innermost, s):")
        for frame, n in lines.most_common(args.top):
            m = re.search(r"\((.+):(\d+)\)$", frame)
            src = linecache.getline(m.group(1), int(m.group(2))).strip()[:70] if m else ""
            print(f"    {n / rate:6.2f}  {frame.split(' (')[0]:40s} {src}")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "cpu_model": cpu_model(),
                    "args": what,
                    "frames": frames_done,
                    "wall_s": wall,
                    "cpu_s": cpu,
                    "stages_s": stages,
                    "categories_s": {k: v / rate for k, v in busy.items()},
                    "native_unsampled_s": max(cpu - sampled_cpu, 0.0),
                    "recording_mb": rrd_mb,
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
