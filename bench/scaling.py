"""How the cost of an ``agrisim run`` grows with resolution, setpoints and shadow samples, so a
sweep's cost can be predicted: whole-process wall time of small runs varied one factor at a time
around a base (20 views; setpoints at 480x270, shadows at 960x540), fitted as fixed + per-view cost, and plotted (``docs/scaling.png``). Prints
figures; asserts nothing.

    python bench/scaling.py                    # the README's sweep (about ten minutes)
    python bench/scaling.py --quick            # fewer points
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

RESOLUTIONS = ["480x270", "960x540", "1440x810", "1920x1080"]
SETPOINTS = ["1x5", "2x10", "5x10", "5x20", "10x20"]  # 10 .. 400 views
SHADOWS = [0, 1, 4, 16, 32]


def run(args: list[str]) -> tuple[float, int, dict[str, float]]:
    """(wall s, frames, stage clocks) of one ``agrisim run`` with ``args``."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "agrisim", "run", "--out", str(out), *args], check=True, stdout=subprocess.DEVNULL
        )
        wall = time.perf_counter() - t0
        doc = json.loads((out / "run.json").read_text())
    return wall, len(doc["frames_complete"]), doc["summary"]["wall_s"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--plot", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "scaling.png")
    args = parser.parse_args()
    res = RESOLUTIONS if not args.quick else RESOLUTIONS[::3]
    sps = SETPOINTS if not args.quick else SETPOINTS[:2]
    shadows = SHADOWS if not args.quick else SHADOWS[::2]
    print(f"{cpu_model()}: whole-process wall time of agrisim run")
    results: dict[str, list[tuple[str, float, int]]] = {"resolution": [], "setpoints": [], "shadow samples": []}
    for r in res:  # 20 views
        wall, n, _ = run(["--setpoints", "2x5", "--resolution", r])
        results["resolution"].append((r, wall, n))
        print(f"  --resolution {r} (20 views): {wall:.1f} s", flush=True)
    for s in sps:  # at 480x270: the robot's share shows
        wall, n, _ = run(["--setpoints", s, "--resolution", "480x270"])
        results["setpoints"].append((s, wall, n))
        print(f"  --setpoints {s} ({n} views, 480x270): {wall:.1f} s", flush=True)
    for k in shadows:  # 20 views at 960x540
        wall, n, _ = run(["--setpoints", "2x5", "--resolution", "960x540", "--shadow-samples", str(k)])
        results["shadow samples"].append((str(k), wall, n))
        print(f"  shadow samples {k} (20 views, 960x540): {wall:.1f} s", flush=True)
    (n0, w0), (n1, w1) = (
        [(n, w) for _, w, n in results["setpoints"]][0],
        [(n, w) for _, w, n in results["setpoints"]][-1],
    )
    per_view = (w1 - w0) / max(n1 - n0, 1)
    print(f"  fit at 480x270: {w0 - per_view * n0:.1f} s fixed + {per_view:.2f} s per view")
    plot(results, args.plot)
    print(f"  plot: {args.plot}")


def plot(results: dict[str, list[tuple[str, float, int]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    x_of = {
        "resolution": lambda label: int(label.split("x")[0]) * int(label.split("x")[1]) / 1e6,
        "setpoints": None,
        "shadow samples": lambda label: int(label),
    }
    titles = {
        "resolution": ("megapixels (20 views)", "resolution"),
        "setpoints": ("views (480x270)", "setpoints"),
        "shadow samples": ("shadow samples per pixel (20 views, 960x540)", "shadow samples"),
    }
    for ax, (key, rows) in zip(axes, results.items(), strict=False):
        xs = [x_of[key](label) if x_of[key] else n for label, _, n in rows]
        ax.plot(xs, [w for _, w, _ in rows], "o-", color="#2a7")
        for x, (label, w, _) in zip(xs, rows, strict=True):
            ax.annotate(label, (x, w), textcoords="offset points", xytext=(4, -10), fontsize=7)
        ax.set_xlabel(titles[key][0])
        ax.set_ylabel("wall time of the run, s")
        ax.set_title(titles[key][1])
        ax.grid(alpha=0.3)
        ax.set_ylim(bottom=0)
    fig.suptitle(f"agrisim run, whole process, on {cpu_model()} (2 cores)", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
