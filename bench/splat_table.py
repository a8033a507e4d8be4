"""The paper's Table 2, right-hand columns: Gaussian splatting (the ``splat`` reconstructor) on
every species' hidden-arm run, held-out PSNR and SSIM beside the paper's nerfacto numbers, with
the geometry columns the paper could not measure. Prints figures; asserts nothing.

Three stages, because the views are labelled and measured on the CPU (Open3D) and rendered and
trained on a GPU machine that takes a small carry:

    python bench/splat_table.py prepare DIR [--species ...]   # CPU: runs, split into a carry
    python bench/splat_table.py gpu DIR WORK [--species ...]  # GPU: agrisim render + recon
    python bench/splat_table.py table METRICS_DIR             # the table, as Markdown

``prepare`` runs ``agrisim run --hide-robots --renderer raycast --recon none`` (100 setpoints,
960x540) per species into DIR/<species>/full and writes DIR/<species>/run (the saved scene and
cameras; empty RGB, label and depth files) and DIR/<species>/truth (the label and depth PNGs),
so that a carry holds the run without its images (the RGB is re-rendered there) and the truth
travels in a second carry. ``gpu --step render`` re-renders each run with Mitsuba (64 samples
per pixel, no denoiser); ``gpu --step train`` puts the truth back, trains and measures with
``agrisim recon --recon splat`` and copies each ``metrics.json`` to WORK/metrics/<species>.json.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

SPECIES = [
    "hydrangea", "indian_cress", "amaryllis", "boston_fern", "common_fern",
    "bog_marshcress", "boxwood", "coltsfoot", "chinese_evergreen", "basket_grass",
]  # fmt: skip
#: the paper's Table 2, nerfacto on COLMAP poses: (PSNR, SSIM)
PAPER = {
    "hydrangea": (26.197, 0.799), "indian_cress": (27.021, 0.816), "amaryllis": (28.234, 0.819),
    "boston_fern": (17.616, 0.680), "common_fern": (28.632, 0.828), "bog_marshcress": (29.007, 0.842),
    "boxwood": (27.710, 0.810), "coltsfoot": (28.785, 0.828), "chinese_evergreen": (28.392, 0.820),
    "basket_grass": (26.321, 0.736),
}  # fmt: skip


def agrisim(*args: str) -> None:
    code = f"import sys; from agrisim.app.cli import main; sys.exit(main({list(args)!r}))"
    subprocess.run([sys.executable, "-c", code], check=True)


def prepare(root: Path, species: list[str], resolution: str) -> None:
    for s in species:
        full = root / s / "full"
        if not (full / "run.json").is_file():
            agrisim("run", "--plant", s, "--hide-robots", "--resolution", resolution, "--recon", "none",
                    "--no-rrd", "--physics", "kinematic", "--out", str(full))  # fmt: skip
        run, truth = root / s / "run", root / s / "truth"
        shutil.rmtree(run, ignore_errors=True)
        shutil.rmtree(truth, ignore_errors=True)
        run.mkdir(parents=True)
        for name in ("run.json", "cameras.json"):
            shutil.copy2(full / name, run / name)
        shutil.copytree(full / "scene", run / "scene")
        for folder in ("labels", "depth"):
            shutil.copytree(full / folder, truth / folder)
        for folder in ("rgb", "labels", "depth"):
            (run / folder).mkdir()
            for png in (full / folder).glob("*.png"):
                (run / folder / png.name).touch()
        size = lambda d: sum(p.stat().st_size for p in d.rglob("*") if p.is_file()) / 1e6  # noqa: E731
        print(f"{s}: carry {size(run):.1f} MB + truth {size(truth):.1f} MB")


def gpu(root: Path, work: Path, species: list[str], step: str) -> None:
    (work / "metrics").mkdir(parents=True, exist_ok=True)
    for s in species:
        out = work / s
        if step in ("render", "both"):
            shutil.rmtree(out, ignore_errors=True)
            agrisim("render", str(root / s / "run"), "--out", str(out),
                    "--set", "renderer.mitsuba.spp=64", "--set", "renderer.mitsuba.denoise=off")  # fmt: skip
        if step in ("train", "both"):
            for folder in ("labels", "depth"):
                for png in (root / s / "truth" / folder).glob("*.png"):
                    shutil.copy2(png, out / folder / png.name)
            agrisim("recon", str(out), "--recon", "splat", "--overwrite")
            shutil.copy2(out / "metrics.json", work / "metrics" / f"{s}.json")
            m = json.loads((out / "metrics.json").read_text())["splat"]
            print(
                s,
                json.dumps({k: m[k] for k in ("psnr", "ssim", "psnr_plant", "gaussians", "train_seconds")}),
                flush=True,
            )


def table(folder: Path) -> None:
    print(
        "| plant | PSNR | SSIM | paper PSNR | paper SSIM | plant PSNR | depth error median / p90, mm | centres precision / recall @2mm | Gaussians | training s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for s in SPECIES:
        path = folder / f"{s}.json"
        if not path.is_file():
            continue
        m = json.loads(path.read_text())["splat"]
        d, g = m["depth_error_mm"], m["geometry"]
        p = PAPER[s]
        print(
            f"| {s.replace('_', ' ')} | {m['psnr']:.2f} | {m['ssim']:.3f} | {p[0]:.2f} | {p[1]:.3f} | {m['psnr_plant']:.2f} "
            f"| {d['median']:.0f} / {d['p90']:.0f} | {g['precision@2mm']:.3f} / {g['recall@2mm']:.3f} | {m['gaussians']:,} | {m['train_seconds']:.0f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("root", type=Path)
    p.add_argument("--species", nargs="+", default=SPECIES)
    p.add_argument("--resolution", default="960x540")
    g = sub.add_parser("gpu")
    g.add_argument("root", type=Path)
    g.add_argument("work", type=Path)
    g.add_argument("--species", nargs="+", default=SPECIES)
    g.add_argument("--step", choices=["render", "train", "both"], default="both")
    t = sub.add_parser("table")
    t.add_argument("folder", type=Path)
    args = parser.parse_args()
    if args.command == "prepare":
        prepare(args.root, args.species, args.resolution)
    elif args.command == "gpu":
        gpu(args.root, args.work, args.species, args.step)
    else:
        table(args.folder)


if __name__ == "__main__":
    main()
