"""The paper's Table 2, right-hand columns: Gaussian splatting (the ``splat`` reconstructor) on
every species' hidden-arm run, held-out PSNR and SSIM beside the paper's nerfacto numbers, with
the plant and geometry columns the paper could not measure, on true poses and on COLMAP's.
Prints figures; asserts nothing.

The views are made on the CPU (a run, its views path-traced again by ``agrisim render`` at the
mitsuba defaults, denoised, and COLMAP's poses of those) and packed for a GPU machine, where
``bench/splat_plant.py`` trains on them, one species a call (a pack is 40-50 MB of a 64 MiB
carry):

    python bench/splat_table.py prepare DIR CARRY [--species ...]   # CPU: DIR/<s>/..., CARRY/<s>
    python bench/splat_plant.py train CARRY/<s> --variant <s> --poses truth colmap --out M  # GPU
    (or the two poses as two processes at once, --variant <s>-truth --poses truth and
    --variant <s>-colmap --poses colmap: both fit on one H100, in less time)
    python bench/splat_table.py table M                            # the tables, as Markdown

Over the GPUs of one host, one species a GPU at a time (a queue: a GPU takes the next species
when its last is done), each species a ``splat_plant.py train`` process on its own GPU
(``CUDA_VISIBLE_DEVICES``), the table's wall time printed and kept in M/gpus-<N>.json::

    python bench/splat_table.py train CARRY --gpus 4 --out M [--draw mitsuba] [--species ...]
    (--devices 1,2 for those GPUs: two tables at once on one host's separate GPUs)

``--draw mitsuba`` takes saved runs (scene, cameras; no images) in CARRY/<s> and path-traces
their views on the GPU first (Mitsuba's defaults), so that ten species fit one 64 MiB carry.

``prepare`` runs ``agrisim run --hide-robots --recon none`` (raycast, 100 setpoints, 960x540)
into DIR/<s>/full where it is not there yet, re-renders it into DIR/<s>/mitsuba, runs
``agrisim colmap`` on that, and packs it (``splat_plant.py pack``) into CARRY/<s>.
"""

from __future__ import annotations

import argparse
import json
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


def prepare(root: Path, carry: Path, species: list[str], resolution: str) -> None:
    from splat_plant import pack

    for s in species:
        full, views = root / s / "full", root / s / "mitsuba"
        if not (full / "run.json").is_file():
            agrisim("run", "--plant", s, "--hide-robots", "--resolution", resolution, "--recon", "none",
                    "--no-rrd", "--physics", "kinematic", "--out", str(full))  # fmt: skip
        agrisim("render", str(full), "--out", str(views))  # resumes an interrupted one
        if not (views / "colmap" / "poses.json").is_file():
            agrisim("colmap", str(views))
        if not (carry / s).exists():
            pack(views, carry / s)


def train_on_gpus(
    carry: Path,
    species: list[str],
    gpus: list[int],
    out: Path,
    draw: str | None,
    through: list[str] | None = None,
    per_gpu: int = 1,
) -> None:
    """Every species of ``carry`` trained on true poses, a ``splat_plant.py train`` process per
    species, one on each GPU of ``gpus`` at once; prints and saves the wall times. Each
    ``through`` (``PRESET:IMAGER``, with ``draw``) trains every species again on views drawn
    through that camera and shot by that imager (variant ``<s>-PRESET-IMAGER``). ``per_gpu``
    trainings share a GPU at once (two take about the time of one on an H100)."""
    import os
    import queue
    import threading
    import time

    here = Path(__file__).resolve().parent
    todo: queue.Queue[tuple[str, str, list[str]]] = queue.Queue()
    for s in species:
        todo.put((s, f"{s}-truth", []))
        for lens in through or []:
            camera, imager = lens.split(":")
            todo.put((s, f"{s}-{camera}-{imager}", ["--camera", camera, "--imager", imager]))
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    t0 = time.perf_counter()

    def worker(gpu: int) -> None:
        while True:
            try:
                s, name, extra = todo.get_nowait()
            except queue.Empty:
                return
            cmd = [sys.executable, str(here / "splat_plant.py"), "train", str(carry / s), "--variant", name,
                   "--poses", "truth", "--out", str(out)] + (["--draw", draw] if draw else []) + extra  # fmt: skip
            start = time.perf_counter() - t0
            with open(out / f"{name}.log", "w") as log:
                done = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, check=False,
                                      env=dict(os.environ, CUDA_VISIBLE_DEVICES=str(gpu)))  # fmt: skip
            end = time.perf_counter() - t0
            rows.append({"species": s, "variant": name, "gpu": gpu, "start_s": round(start, 1),
                         "end_s": round(end, 1), "status": done.returncode})  # fmt: skip
            print(f"{name}: GPU {gpu}, {start:.0f}-{end:.0f} s, exit {done.returncode}", flush=True)

    threads = [threading.Thread(target=worker, args=(g,)) for g in gpus for _ in range(per_gpu)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - t0
    busy = sum(r["end_s"] - r["start_s"] for r in rows)
    print(f"{len(species)} species on {len(gpus)} GPUs: {wall:.0f} s wall, {busy:.0f} s of training", flush=True)
    doc = {"gpus": gpus, "species": species, "draw": draw, "wall_s": round(wall, 1), "runs": rows}
    (out / f"gpus-{len(gpus)}.json").write_text(json.dumps(doc, indent=1) + "\n")


def table(folder: Path) -> None:
    print(
        "| plant | PSNR | SSIM | paper PSNR | paper SSIM | plant PSNR | plant depth error median / p90, mm | centres precision / recall @2mm | Gaussians | training s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for s in SPECIES:
        path = folder / f"{s}-truth.json"
        if not path.is_file():
            continue
        m = json.loads(path.read_text())["splat"]
        d, g = m["depth_error_mm"], m["geometry"]
        p = PAPER[s]
        print(
            f"| {s.replace('_', ' ')} | {m['psnr']:.2f} | {m['ssim']:.3f} | {p[0]:.2f} | {p[1]:.3f} | {m['psnr_plant']:.2f} "
            f"| {d['median']:.1f} / {d['p90']:.0f} | {g['precision@2mm']:.3f} / {g['recall@2mm']:.3f} | {m['gaussians']:,} | {m['train_seconds']:.0f} |"
        )
    print()
    print("| plant | views placed by COLMAP | PSNR true / COLMAP poses | SSIM | plant PSNR | plant recall @2mm |")
    print("|---|---|---|---|---|---|")
    for s in SPECIES:
        paths = [folder / f"{s}-{poses}.json" for poses in ("truth", "colmap")]
        if not all(p.is_file() for p in paths):
            continue
        t, c = (json.loads(p.read_text())["splat"] for p in paths)
        placed = c["train_views"] + c["test_views"]

        def pair(key: str, f: str, t: dict = t, c: dict = c) -> str:
            return f"{t[key]:{f}} / {c[key]:{f}}"

        recall = f"{t['geometry']['recall@2mm']:.3f} / {c['geometry']['recall@2mm']:.3f}"
        print(
            f"| {s.replace('_', ' ')} | {placed} | {pair('psnr', '.2f')} | {pair('ssim', '.3f')} "
            f"| {pair('psnr_plant', '.2f')} | {recall} |"
        )


def lens_table(folder: Path) -> None:
    """Each species on the pinhole's noise-free views against the same views through a lens and
    an imager (the ``through`` variants), where both were trained."""
    for path in sorted(folder.glob("*-truth.json")):
        s = path.name[: -len("-truth.json")]
        for other in sorted(folder.glob(f"{s}-*-*.json")):
            if other == path or other.name.endswith("-colmap.json"):
                continue
            t, c = (json.loads(p.read_text())["splat"] for p in (path, other))
            label = other.stem[len(s) + 1 :]
            print(
                f"| {s.replace('_', ' ')} | {label} | {t['psnr']:.2f} / {c['psnr']:.2f} | {t['ssim']:.3f} / {c['ssim']:.3f} "
                f"| {t['psnr_plant']:.2f} / {c['psnr_plant']:.2f} "
                f"| {t['geometry']['recall@2mm']:.3f} / {c['geometry']['recall@2mm']:.3f} |"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("prepare")
    p.add_argument("root", type=Path)
    p.add_argument("carry", type=Path)
    p.add_argument("--species", nargs="+", default=SPECIES)
    p.add_argument("--resolution", default="960x540")
    g = sub.add_parser("train")
    g.add_argument("carry", type=Path)
    g.add_argument("--gpus", type=int, help="GPUs 0..N-1")
    g.add_argument("--devices", help="these GPUs, e.g. 1,2 (instead of --gpus)")
    g.add_argument("--out", type=Path, required=True)
    g.add_argument("--draw", metavar="RENDERER")
    g.add_argument("--species", nargs="+", default=SPECIES)
    g.add_argument("--per-gpu", type=int, default=1, help="trainings sharing a GPU at once (default: 1)")
    g.add_argument(
        "--through", action="append", metavar="PRESET:IMAGER", help="also each species through a lens and imager"
    )
    t = sub.add_parser("table")
    t.add_argument("folder", type=Path)
    args = parser.parse_args()
    if args.command == "prepare":
        prepare(args.root, args.carry, args.species, args.resolution)
    elif args.command == "train":
        gpus = [int(d) for d in args.devices.split(",")] if args.devices else list(range(args.gpus or 1))
        train_on_gpus(args.carry, args.species, gpus, args.out, args.draw, args.through, args.per_gpu)
    else:
        table(args.folder)
        print()
        print("| plant | views | PSNR pinhole / these | SSIM | plant PSNR | plant recall @2mm |")
        print("|---|---|---|---|---|---|")
        lens_table(args.folder)


if __name__ == "__main__":
    main()
