"""How robust ``agrisim colmap`` is, without a second CPU: the test's 36 views (coltsfoot,
960x540, raycast with 8 shadow rays, the arms hidden) perturbed as another machine would give
them, each configuration run on each perturbation; one markdown row a pair: views placed
(registered in a kept model), within 20 mm of the truth, median centre error, seconds. Prints
the CPU model first; asserts nothing (tests/e2e/test_colmap.py asserts the band).

    python bench/colmap_robustness.py OUT [--noise 3] [--seeds 5] [--configs robot images stock]

Perturbations: the views as rendered; each re-encoded with +-1 grey level of noise (``--noise``
copies); COLMAP's seeds 1..``--seeds``-1; SIFT on one thread. Configurations: ``robot`` (the
default: the robot's priors, exhaustive matching), ``images`` (``--priors none``: COLMAP from the
images alone, exhaustive matching, the rendered views' SIFT threshold), ``stock`` (the images
alone at COLMAP's own SIFT threshold, one mapping: what ``agrisim colmap`` ran before).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

from agrisim.plugins.poses.colmap.photogrammetry import COLMAP_PEAK_THRESHOLD  # noqa: E402

CONFIGS = {
    "robot": {},
    "images": {"priors": "none"},
    "stock": {"priors": "none", "peak_threshold": COLMAP_PEAK_THRESHOLD, "attempts": 1},
}


def test_run(out: Path) -> Path:
    """The 36 views of tests/e2e/test_colmap.py (the same settings), made once into ``out``."""
    from agrisim.config import build_config, merge
    from agrisim.episode import Episode

    if (out / "run.json").is_file():
        return out
    cfg = {
        "plant": "coltsfoot",
        "physics": {"backend": "kinematic"},
        "routine": {"setpoints": "3x6", "theta_deg": [50.0, 130.0], "phi_deg": [40.0, 70.0]},
        "camera": {"resolution": "960x540"},
        "render": {"hide_robots": True},
        "renderer": {"raycast": {"shadow_samples": 8}},
        "recon": {"backend": "none"},
        "output": {"out": str(out), "no_rrd": True},
    }
    Episode(build_config(merge({}, cfg))).run()
    return out


def main() -> None:
    from agrisim.plugins.poses.colmap.photogrammetry import run_colmap
    from agrisim.testing.perturb import noisy_copy

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--noise", type=int, default=3, help="noisy copies of the views (3)")
    parser.add_argument("--seeds", type=int, default=5, help="COLMAP seeds 0..N-1 (5)")
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    args = parser.parse_args()
    print(f"CPU: {cpu_model()}")
    base = test_run(args.out / "views")
    cases: list[tuple[str, Path, dict]] = [("as rendered", base, {})]
    for k in range(args.noise):
        copy = args.out / f"noise-{k}"
        if not copy.exists():
            noisy_copy(base, copy, seed=k)
        cases.append((f"+-1 grey, noise seed {k}", copy, {}))
    cases += [(f"COLMAP seed {s}", base, {"seed": s}) for s in range(1, args.seeds)]
    cases.append(("SIFT on 1 thread", base, {"feature_threads": 1}))
    print("| configuration | views given | placed | within 20 mm | median centre error mm | s |")
    print("|---|---|---|---|---|---|")
    for name in args.configs:
        for label, run, extra in cases:
            start = time.perf_counter()
            result = run_colmap(run, overwrite=True, **CONFIGS[name], **extra)
            s = result.summary()
            med = "-" if s["median_centre_error_mm"] is None else f"{s['median_centre_error_mm']:.2f}"
            print(
                f"| {name} | {label} | {s['registered']}/{s['views']} | {s['within_20mm']} | {med} | "
                f"{time.perf_counter() - start:.0f} |",
                flush=True,
            )
    (args.out / "settings.json").write_text(json.dumps(CONFIGS, indent=1))


if __name__ == "__main__":
    main()
