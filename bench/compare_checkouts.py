"""Two checkouts of agrisim side by side on one machine: the default run, the robot-only run
and the recording, timed alternately (before, after, before, after...), and the outputs compared
(images by pixel, clouds, metrics and trajectories by value). Prints figures and ratios; asserts
nothing. Each checkout needs its own environment (``make setup`` in it).

    git worktree add ../before <commit> && make -C ../before setup
    python bench/compare_checkouts.py ../before .              # both runs, twice each
    python bench/compare_checkouts.py ../before . --only robot --repeat 3
    python bench/compare_checkouts.py ../before . --only recording   # with and without --no-rrd
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from decimal import Decimal
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

#: run.json / metrics.json keys that hold clocks, paths or versions, not results
VOLATILE = re.compile(r"(_s|started_at|command|versions|out_dir|^out)$")


def timed(cmd: list[str], cwd: Path) -> tuple[float, float, float]:
    """Run ``cmd``; (wall s, peak RSS MB, CPU s of the process)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr.read().decode()[-2000:]}")
    return wall, usage.ru_maxrss / 1024, usage.ru_utime + usage.ru_stime


def python_of(checkout: Path) -> str:
    exe = checkout / ".venv" / "bin" / "python"
    if not exe.exists():
        raise SystemExit(f"{checkout} has no .venv: run `make setup` there first")
    return str(exe)


def _strip(doc: object) -> object:
    if isinstance(doc, dict):
        return {k: _strip(v) for k, v in doc.items() if not VOLATILE.search(k)}
    if isinstance(doc, list):
        return [_strip(v) for v in doc]
    return doc


def _files(root: Path) -> set[Path]:
    return {p.relative_to(root) for p in root.rglob("*") if p.is_file()}


def one_sided(a: Path, b: Path) -> list[str]:
    """Files only one of two run directories has, by folder: ``only after: trajectories/ (100
    files)`` (a newer checkout may write more than an older one)."""
    files_a, files_b = _files(a), _files(b)
    out = []
    for side, only in (("before", files_a - files_b), ("after", files_b - files_a)):
        folders: dict[str, int] = {}
        for rel in only:
            key = f"{rel.parts[0]}/" if len(rel.parts) > 1 else str(rel)
            folders[key] = folders.get(key, 0) + 1
        out += [f"only {side}: {k} ({n} file{'s' if n > 1 else ''})" for k, n in sorted(folders.items())]
    return out


def _decimals(x: float) -> int:
    """Decimal places of the shortest text that reads back as ``x`` (5.30261e-07: 12)."""
    return max(-int(Decimal(repr(x)).as_tuple().exponent), 0)


def _same_values(a: object, b: object) -> bool:
    """Equal JSON values, where a number written to fewer decimals by one side (an older
    checkout rounded poses to 12) equals the other rounded alike, and a dict key only one side
    has (an option added since) is not compared."""
    if isinstance(a, dict) and isinstance(b, dict):
        return all(_same_values(a[k], b[k]) for k in a.keys() & b.keys())
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same_values(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and a != b:
        places = min(_decimals(a), _decimals(b))
        return round(a, places) == round(b, places)
    return a == b


def same_outputs(a: Path, b: Path) -> list[str]:
    """What differs between the files two run directories both have (empty: images equal pixel
    for pixel, JSON equal in value (run.json and metrics.json but for clocks), every other file
    equal byte for byte)."""
    problems = []
    for rel in sorted(_files(a) & _files(b)):
        pa, pb = a / rel, b / rel
        if rel.suffix == ".png":
            if not np.array_equal(np.asarray(Image.open(pa)), np.asarray(Image.open(pb))):
                problems.append(f"pixels differ: {rel}")
        elif rel.suffix == ".json":
            if pa.read_bytes() != pb.read_bytes() and not _same_values(
                _strip(json.loads(pa.read_text())), _strip(json.loads(pb.read_text()))
            ):
                problems.append(f"values differ: {rel}")
        elif rel.suffix == ".rrd":
            continue  # the recording's chunking may change on purpose (its size is reported)
        elif pa.read_bytes() != pb.read_bytes():
            problems.append(f"bytes differ: {rel}")
    return problems


def image_agreement(a: Path, b: Path) -> str:
    """How far two runs' images agree, view by view: labels (share of equal pixels, worst view),
    depth in whole millimetres (pixels that differ where both see something), RGB (PSNR in dB,
    worst and mean view)."""
    labels, depth, psnr = [], [], []
    for pa in sorted((a / "labels").glob("*.png")):
        pb = b / "labels" / pa.name
        if pb.exists():
            labels.append(float((np.asarray(Image.open(pa)) == np.asarray(Image.open(pb))).mean()))
    for pa in sorted((a / "depth").glob("*.png")):
        pb = b / "depth" / pa.name
        if pb.exists():
            da, db = np.asarray(Image.open(pa)).astype(int), np.asarray(Image.open(pb)).astype(int)
            both = (da > 0) & (db > 0)
            depth.append(int(((da != db) & both).sum()))
    for pa in sorted((a / "rgb").glob("*.png")):
        pb = b / "rgb" / pa.name
        if pb.exists():
            mse = float(((np.asarray(Image.open(pa)).astype(float) - np.asarray(Image.open(pb))) ** 2).mean())
            psnr.append(10 * np.log10(255.0**2 / mse) if mse > 0 else float("inf"))
    if not labels:
        return "no images"
    return (
        f"labels equal on {100 * min(labels):.4f}% of the pixels of the worst view (mean {100 * np.mean(labels):.4f}%); "
        f"depth (mm) differs on {max(depth)} pixels of the worst view where both see something; "
        f"RGB PSNR {min(psnr):.1f} dB worst view, {np.mean(psnr):.1f} mean"
    )


def rrd_chunks(python: str, rrd: Path) -> tuple[int, int]:
    """(chunks, theoretical lower bound) that ``rerun rrd stats`` reports (-1: not said)."""
    rerun = Path(python).with_name("rerun")
    out = subprocess.run([str(rerun), "rrd", "stats", str(rrd)], capture_output=True, text=True).stdout
    number = r"(\d[\d\s\u202f\u00a0]*)"
    chunks = re.search(r"num_chunks = " + number, out)
    bound = re.search(r"lower bound:\s+" + number + " chunks", out)
    as_int = lambda m: int(re.sub(r"\D", "", m.group(1))) if m else -1  # noqa: E731
    return as_int(chunks), as_int(bound)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--only", choices=("default", "robot", "recording"), default=None)
    parser.add_argument("--setpoints", default=None, help="LxC for the default run (default 5x10)")
    args = parser.parse_args()
    sides = {"before": args.before.resolve(), "after": args.after.resolve()}
    pythons = {k: python_of(v) for k, v in sides.items()}
    commits = {
        k: subprocess.run(
            ["git", "-C", str(v), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        for k, v in sides.items()
    }
    print(f"{cpu_model()}; before {commits['before']} ({sides['before']}), after {commits['after']} ({sides['after']})")
    runs = {"default": [], "robot": ["--renderer", "none"]}
    if args.setpoints:
        runs["default"] += ["--setpoints", args.setpoints]
    with tempfile.TemporaryDirectory() as tmp:
        if args.only == "recording":
            recording_cost(pythons, sides, runs["default"], args.repeat, Path(tmp))
            return
        for name, extra in runs.items():
            if args.only and name != args.only:
                continue
            walls: dict[str, list[float]] = {"before": [], "after": []}
            peaks: dict[str, list[float]] = {"before": [], "after": []}
            for i in range(args.repeat):
                for side in ("before", "after"):
                    out = Path(tmp) / f"{name}-{side}-{i}"
                    wall, peak, _ = timed(
                        [pythons[side], "-m", "agrisim", "run", "--out", str(out), *extra], sides[side]
                    )
                    walls[side].append(wall)
                    peaks[side].append(peak)
                    print(f"  {name} run, {side}: {wall:.1f} s, peak RSS {peak:.0f} MB", flush=True)
            problems = same_outputs(Path(tmp) / f"{name}-before-0", Path(tmp) / f"{name}-after-0")
            b, a = min(walls["before"]), min(walls["after"])
            print(
                f"{name} run: before {b:.1f} s, after {a:.1f} s (best of {args.repeat}): {a / b:.2f}x; "
                f"peak RSS {max(peaks['before']):.0f} -> {max(peaks['after']):.0f} MB; "
                f"outputs {'identical' if not problems else 'DIFFER: ' + '; '.join(problems[:8])} in the files both write"
            )
            extra = one_sided(Path(tmp) / f"{name}-before-0", Path(tmp) / f"{name}-after-0")
            if extra:
                print(f"  {'; '.join(extra)}")
            if problems:
                print(f"  images: {image_agreement(Path(tmp) / f'{name}-before-0', Path(tmp) / f'{name}-after-0')}")
            rrd = {s: Path(tmp) / f"{name}-{s}-0" / "recording.rrd" for s in sides}
            if all(p.exists() for p in rrd.values()):
                for s in sides:
                    chunks, bound = rrd_chunks(pythons["after"], rrd[s])
                    print(
                        f"  recording {s}: {rrd[s].stat().st_size / 1e6:.0f} MB, {chunks} chunks (lower bound {bound})"
                    )


def recording_cost(pythons: dict[str, str], sides: dict[str, Path], extra: list[str], repeat: int, tmp: Path) -> None:
    """What writing the recording costs each side: the default run with it against the same run
    with ``--no-rrd``, alternating; wall and CPU time (Rerun encodes and writes in threads of
    its own, so CPU shows the work even where wall time hides it)."""
    figures: dict[tuple[str, bool], list[tuple[float, float]]] = {}
    for i in range(repeat):
        for side in ("before", "after"):
            for rrd in (True, False):
                out = tmp / f"rec-{side}-{rrd}-{i}"
                wall, _, cpu = timed(
                    [pythons[side], "-m", "agrisim", "run", "--out", str(out), *extra, *([] if rrd else ["--no-rrd"])],
                    sides[side],
                )
                figures.setdefault((side, rrd), []).append((wall, cpu))
                size = (out / "recording.rrd").stat().st_size / 1e6 if rrd else 0.0
                print(
                    f"  {side}, {'with the recording' if rrd else '--no-rrd'}: {wall:.1f} s wall, {cpu:.1f} s CPU"
                    + (f", recording {size:.0f} MB" if rrd else ""),
                    flush=True,
                )
    for side in ("before", "after"):
        with_, without = (min(figures[(side, r)]) for r in (True, False))
        cpu_with, cpu_without = (min(c for _, c in figures[(side, r)]) for r in (True, False))
        print(
            f"recording cost, {side}: {with_[0] - without[0]:+.1f} s wall, {cpu_with - cpu_without:+.1f} s CPU (best of {repeat})"
        )


if __name__ == "__main__":
    main()
