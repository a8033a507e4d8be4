"""How robust ``agrisim colmap`` is, without a second CPU: the views of tests/e2e/test_colmap.py
(:data:`VIEWS`: coltsfoot, 18 views at 960x540, raycast with 8 shadow rays, the arms hidden)
perturbed as another machine would give them, and every configuration run on each perturbation
as the tests run it; one markdown row a case. Prints the CPU model first; asserts nothing
(tests/e2e/test_colmap.py asserts the band).

    python bench/colmap_robustness.py OUT [--noise 3] [--threads -1 1] [--seeds 3] [--configs robot images stock]
        [--setpoints 3x3 --theta 50 74 --phi 40 64 --resolution 960x540]

The views as an AVX2 machine renders them (Dr.Jit's kernels 8 lanes wide; tests/conftest.py),
into another OUT: ``AGRISIM_LLVM_TARGET=avx2 OPENBLAS_CORETYPE=Haswell
NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" python bench/colmap_robustness.py OUT2``.

Perturbations, every combination of: the views as rendered or re-encoded with +-1 grey level of
noise (``--noise`` copies, noise seeds 0..N-1); SIFT on every core (-1) or on one thread
(``--threads``); COLMAP's seeds 0..``--seeds``-1 for the mapper. As in the tests, SIFT and
matching run once for each set of views and SIFT threads (matching at the first seed), and each
mapper seed maps those matches once (one attempt: no retry with the next seed hides a failure).
The first test runs the views as rendered, every core, seed 0; the perturbation test a noisy copy
(noise seed 1), one thread, seeds 0-2.

Configurations: ``robot`` (the default: the robot's priors, exhaustive matching), ``images``
(``--priors none``: COLMAP from the images alone, exhaustive matching, the rendered views' SIFT
threshold), ``stock`` (the images alone at COLMAP's own SIFT threshold: what ``agrisim colmap``
ran before). A row: views placed (registered in a kept model), within 20 mm of the truth after
the alignment; with the robot's priors also without any alignment (the models are in the world:
how the perturbation test scores them), the median centre errors, the median rotation error,
the reprojection error, and the verified pairs of 100 inliers or more (what the mapper needs to
start a model: each arm needs one).

``--setpoints``, ``--theta``, ``--phi`` and ``--resolution`` measure other views than the test's
(the test had 36 views, ``--setpoints 3x6 --theta 50 130``, until 2026-11-29).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

from agrisim.plugins.poses.colmap.photogrammetry import COLMAP_PEAK_THRESHOLD  # noqa: E402

CONFIGS = {
    "robot": {},
    "images": {"priors": "none"},
    "stock": {"priors": "none", "peak_threshold": COLMAP_PEAK_THRESHOLD},
}

#: the views of tests/e2e/test_colmap.py's ``run_dir`` (keep the two the same)
VIEWS = {
    "plant": "coltsfoot",
    "routine": {"setpoints": "3x3", "theta_deg": [50.0, 74.0], "phi_deg": [40.0, 64.0]},
    "camera": {"resolution": "960x540"},
    "render": {"hide_robots": True},
    "renderer": {"raycast": {"shadow_samples": 8}},
}


def test_run(out: Path, views: dict[str, Any]) -> Path:
    """The ``views`` (:data:`VIEWS`: the test's), rendered once into ``out``."""
    from agrisim.config import build_config, merge
    from agrisim.episode import Episode

    if (out / "run.json").is_file():
        return out
    cfg = {
        **views,
        "physics": {"backend": "kinematic"},
        "recon": {"backend": "none"},
        "output": {"out": str(out), "no_rrd": True},
    }
    Episode(build_config(merge({}, cfg))).run()
    return out


def _once(pg: Any, cache: Path) -> dict[str, Any]:
    """SIFT and matching made once for each set of inputs, as the tests make them: each later
    call with the same arguments on the same image bytes gets a copy of the database."""
    extract, match = pg.extract_features, pg.match_features
    made: dict[str, tuple[Path, Any, int]] = {}
    state: dict[str, Any] = {"features": "", "strong": 0}

    def extract_once(database, rgb, names, K, intrinsics, max_features, peak_threshold, threads=-1, lens=None):  # noqa: ANN001, ANN202
        key = hashlib.sha256(
            repr((names, np.asarray(K).tolist(), intrinsics, max_features, peak_threshold, threads, lens)).encode()
        )
        for name in names:
            key.update(hashlib.sha256((Path(rgb) / name).read_bytes()).digest())
        state["features"] = key.hexdigest()
        if key.hexdigest() not in made:
            extract(database, rgb, names, K, intrinsics, max_features, peak_threshold, threads, lens)
            made[key.hexdigest()] = (shutil.copyfile(database, cache / f"{len(made)}.db"), None, 0)
        shutil.copyfile(made[key.hexdigest()][0], database)

    def match_once(database, matcher, overlap, rotations=None):  # noqa: ANN001, ANN202
        key = repr((state["features"], matcher, overlap, rotations is None))
        if key not in made:
            pairs = match(database, matcher, overlap, rotations)
            made[key] = (shutil.copyfile(database, cache / f"{len(made)}.db"), pairs, _strong_pairs(database))
        shutil.copyfile(made[key][0], database)
        state["strong"] = made[key][2]
        return made[key][1]

    pg.extract_features, pg.match_features = extract_once, match_once
    return state


def _raw_errors_m(run: Path) -> list[float]:
    """Each view's centre distance from the truth in the kept models as written, no alignment."""
    import pycolmap

    truth = json.loads((run / "cameras.json").read_text())["frames"]
    sparse = run / "colmap" / "sparse"
    return [
        float(
            np.linalg.norm(
                img.projection_center() - np.asarray(truth[img.name.removesuffix(".png")]["world_T_camera"])[:3, 3]
            )
        )
        for model in sparse.iterdir()
        for img in pycolmap.Reconstruction(model).images.values()
        if img.has_pose
    ]


def main() -> None:
    from agrisim.plugins.poses.colmap import photogrammetry as pg
    from agrisim.testing.perturb import noisy_copy

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--noise", type=int, default=3, help="noisy copies of the views (3)")
    parser.add_argument("--threads", type=int, nargs="+", default=[-1, 1], help="SIFT threads (-1 1)")
    parser.add_argument("--seeds", type=int, default=3, help="the mapper's seeds 0..N-1 (3)")
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    parser.add_argument("--setpoints", default=VIEWS["routine"]["setpoints"])
    parser.add_argument("--theta", type=float, nargs=2, default=VIEWS["routine"]["theta_deg"])
    parser.add_argument("--phi", type=float, nargs=2, default=VIEWS["routine"]["phi_deg"])
    parser.add_argument("--resolution", default=VIEWS["camera"]["resolution"])
    args = parser.parse_args()
    views = {
        **VIEWS,
        "routine": {"setpoints": args.setpoints, "theta_deg": list(args.theta), "phi_deg": list(args.phi)},
        "camera": {"resolution": args.resolution},
    }
    print(f"CPU: {cpu_model()}")
    print(f"views: {json.dumps(views)}")
    cache = args.out / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)
    state = _once(pg, cache)
    base = test_run(args.out / "views", views)
    copies: list[tuple[str, Path]] = [("as rendered", base)]
    for k in range(args.noise):
        copy = args.out / f"noise-{k}"
        if not copy.exists():
            noisy_copy(base, copy, seed=k)
        copies.append((f"+-1 grey, noise seed {k}", copy))
    print(
        "| configuration | views | SIFT threads | seed | placed | within 20 mm | unaligned within 20 mm "
        "| median centre error mm | unaligned median mm | median rotation deg | reprojection px "
        "| pairs of 100 inliers | s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for name in args.configs:
        for label, run in copies:
            for threads in args.threads:
                for seed in range(args.seeds):
                    start = time.perf_counter()
                    result = pg.run_colmap(
                        run, overwrite=True, **CONFIGS[name], seed=seed, attempts=1, feature_threads=threads
                    )
                    s = result.summary()
                    raw = _raw_errors_m(run) if name == "robot" else []
                    strong = state["strong"]
                    med = "-" if s["median_centre_error_mm"] is None else f"{s['median_centre_error_mm']:.2f}"
                    rot = "-" if s["median_rotation_error_deg"] is None else f"{s['median_rotation_error_deg']:.3f}"
                    rep = "-" if s["reprojection_px"] is None else f"{s['reprojection_px']:.3f}"
                    raw_in = str(sum(e <= 0.02 for e in raw)) if raw else "-"
                    raw_med = f"{np.median(raw) * 1e3:.2f}" if raw else "-"
                    rows.append(
                        {
                            "config": name,
                            "case": label,
                            "threads": threads,
                            "seed": seed,
                            **s,
                            "unaligned_mm": [e * 1e3 for e in raw],
                        }
                    )
                    print(
                        f"| {name} | {label} | {threads} | {seed} | {s['registered']}/{s['views']} | {s['within_20mm']} "
                        f"| {raw_in} | {med} | {raw_med} | {rot} | {rep} | {strong} | {time.perf_counter() - start:.0f} |",
                        flush=True,
                    )
    (args.out / "settings.json").write_text(json.dumps({"views": views, "configs": CONFIGS}, indent=1))
    (args.out / "rows.json").write_text(json.dumps(rows, indent=1, default=str))


def _strong_pairs(database: Path) -> int:
    """The verified pairs of 100 inliers or more in a matched ``database``."""
    import pycolmap

    db = pycolmap.Database.open(database)
    try:
        return sum(len(g.inlier_matches) >= 100 for g in db.read_two_view_geometries()[1])
    finally:
        db.close()


if __name__ == "__main__":
    main()
