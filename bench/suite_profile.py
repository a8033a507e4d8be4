"""Where the suite's time goes, module by module: set-up, calls and teardown (seconds, as pytest
measured them where each test ran), the CPU seconds its Python processes used (pytest's worker
and the children that exited), and what each module built: Ray clusters started, Dr.Jit
kernels compiled (from scratch, and loaded from Dr.Jit's disk cache) with the compilers' seconds,
plants grown, episodes run, the seconds motion plans spent failing (a failed plan spends its
whole budget), browsers and ``agrisim`` processes started. Counted in every Python
process the suite starts, children included (``bench/suite_profile_site``).

    .venv/bin/python bench/suite_profile.py                      # the suite as `make test` runs it
    .venv/bin/python bench/suite_profile.py --save prof.json -- tests/unit -n 2
    .venv/bin/python bench/suite_profile.py --load prof.json --top 40   # the table again

Under the AVX2 emulation, with the variables ``tests/conftest.py`` names::

    AGRISIM_TEST_CPU=avx2 OPENBLAS_CORETYPE=Haswell NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" \\
        .venv/bin/python bench/suite_profile.py

The table is Markdown; the header names the CPU, its vector ISA and the emulated target.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SITE = Path(__file__).resolve().parent / "suite_profile_site"
#: pytest's arguments as `make test` gives them (the Makefile's test target)
MAKE_TEST_ARGS = [
    "-q",
    "-n",
    "auto",
    "--maxprocesses=4",
    "--dist",
    "loadfile",
    "--no-loadscope-reorder",
    "--durations=15",
    "tests",
]
COLUMNS = (
    "setup",
    "call",
    "teardown",
    "total",
    "cpu s",
    "tests",
    "ray",
    "compiled",
    "from disk",
    "compile s",
    "plants",
    "runs",
    "failed plans s",
    "browsers",
    "agrisim",
)


def run_suite(pytest_args: list[str]) -> dict:
    """Run pytest with the counters; the events and the wall time."""
    with tempfile.TemporaryDirectory(prefix="suite-profile-") as events:
        env = dict(os.environ, SUITE_PROFILE_DIR=events)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(SITE), env.get("PYTHONPATH", "")) if p)
        start, busy = time.perf_counter(), _machine_ticks()
        proc = subprocess.run(
            [sys.executable, "-m", "pytest", "-p", "suite_profile_plugin", *pytest_args], cwd=ROOT, env=env
        )
        wall = time.perf_counter() - start
        used, total = (b - a for a, b in zip(busy, _machine_ticks(), strict=True))
        rows = []
        for path in Path(events).glob("*.jsonl"):
            for line in path.read_text().splitlines():
                try:
                    rows.append(json.loads(line))
                except json.JSONDecodeError:  # a process killed mid-line
                    pass
    busy_share = used / total if total else 0.0
    return {
        "wall": wall,
        "exit": proc.returncode,
        "args": pytest_args,
        "cpu": _cpu(),
        "busy": busy_share,
        "events": rows,
    }


def _machine_ticks() -> tuple[int, int]:
    """The whole machine's busy and total CPU ticks so far (/proc/stat), children of every kind
    included (Chromium, Ray's C++ daemons) that the per-process counters cannot see."""
    try:
        fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    except (OSError, ValueError):
        return 0, 0
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle + iowait
    return sum(fields) - idle, sum(fields)


def _cpu() -> str:
    sys.path.insert(0, str(ROOT))
    try:
        from agrisim.plugins.render.mitsuba.cpu import cpu_model, vector_isa

        line = f"{cpu_model()} ({vector_isa()})"
    except Exception as exc:  # noqa: BLE001 - only a header
        line = f"unknown CPU ({exc})"
    if os.environ.get("AGRISIM_TEST_CPU"):
        line += f", emulating {os.environ['AGRISIM_TEST_CPU']} (AGRISIM_TEST_CPU)"
    return line + f", {os.cpu_count()} cores"


def _module(test: str) -> str:
    return test.split("::", 1)[0] if test else "(outside any test)"


def summarise(profile: dict) -> tuple[dict[str, dict[str, float]], dict[str, float]]:
    """Per module: the columns; per worker: its seconds."""
    table: dict[str, dict[str, float]] = defaultdict(lambda: dict.fromkeys(COLUMNS, 0.0))
    workers: dict[str, float] = defaultdict(float)
    tests: dict[str, set[str]] = defaultdict(set)
    for e in profile["events"]:
        kind = e["kind"]
        if kind == "phase":
            row = table[_module(e["node"])]
            row[e["when"]] += e["secs"]
            row["total"] += e["secs"]
            workers[e["worker"]] += e["secs"]
            tests[_module(e["node"])].add(e["node"])
            continue
        row = table[_module(e["test"])]
        if kind == "ray":
            row["ray"] += 1
        elif kind == "kernels":
            row["compiled"] += e["compiled"]
            row["from disk"] += e["from_disk"]
            row["compile s"] += e["secs"]
        elif kind == "cpu":
            row["cpu s"] += e["secs"]
        elif kind == "plant":
            row["plants"] += 1
        elif kind == "run":
            row["runs"] += 1
        elif kind == "plan" and e["detail"] == "failed":
            row["failed plans s"] += e["secs"]
        elif kind == "process" and e["detail"] in ("browser", "agrisim"):
            row["browsers" if e["detail"] == "browser" else "agrisim"] += 1
    for module, nodes in tests.items():
        table[module]["tests"] = len(nodes)
    return dict(table), dict(workers)


def render(profile: dict, top: int) -> str:
    table, workers = summarise(profile)
    rows = sorted(table.items(), key=lambda kv: -kv[1]["total"])
    lines = [
        f"suite profile: {profile['cpu']}; pytest {' '.join(profile['args'])}",
        f"wall {profile['wall']:.0f} s (exit {profile['exit']}); machine busy {profile.get('busy', 0):.0%}; per worker: "
        + ", ".join(f"{w} {s:.0f} s" for w, s in sorted(workers.items())),
        "",
        "| module | " + " | ".join(COLUMNS) + " |",
        "|---|" + "---:|" * len(COLUMNS),
    ]
    totals = dict.fromkeys(COLUMNS, 0.0)
    for _module, row in rows:
        for c in COLUMNS:
            totals[c] += row[c]
    for module, row in [*rows[:top], ("**all**", totals)]:
        cells = [f"{row[c]:.1f}" if c in ("compile s", "failed plans s") else f"{row[c]:.0f}" for c in COLUMNS]
        lines.append(f"| {module} | " + " | ".join(cells) + " |")
    if len(rows) > top:
        lines.insert(-1, f"| ({len(rows) - top} more modules) | " + " | ".join("" for _ in COLUMNS) + " |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--save", type=Path, help="keep the events in this JSON file")
    parser.add_argument("--load", type=Path, help="print the table of a saved profile instead of running")
    parser.add_argument("--top", type=int, default=30, help="modules shown, slowest first (default 30)")
    parser.add_argument("pytest_args", nargs="*", help="pytest's arguments after --; default: as `make test`")
    args = parser.parse_args()
    if args.load:
        profile = json.loads(args.load.read_text())
    else:
        profile = run_suite(args.pytest_args or MAKE_TEST_ARGS)
        if args.save:
            args.save.write_text(json.dumps(profile))
    print(render(profile, args.top))
    return int(profile["exit"])


if __name__ == "__main__":
    sys.exit(main())
