"""COLMAP through a real camera, on path-traced views: every species' saved run (scene and
cameras, no images) drawn again by Mitsuba on a GPU, once through the pinhole it was made with
(noise-free) and once through a lens and an imager (each arm's camera auto-exposing from view to
view in capture order), the same draws as the splat table's ``--through`` columns; then
``agrisim colmap``'s pipeline on each, many at once on the CPU cores. Prints figures; asserts
nothing. For a GPU machine of several cores: the draws need Mitsuba (bench/device_site.sh),
COLMAP needs pycolmap (``bench/device_site.sh OUT pycolmap==4.2.1``), so the two stages can be
two calls on one warm machine, each with its own carry::

    python bench/colmap_through.py draw SAVED OUT [--through rpi-camera-3-wide:imx708] [--gpus 4]
        [--species ...] [--set spp=8 ...]        # OUT/<s>-pinhole/, OUT/<s>-<preset>-<imager>/
    python bench/colmap_through.py colmap OUT [--jobs 20] [--threads 3]   # OUT/*/colmap/
    python bench/colmap_through.py table OUT     # Markdown: pinhole -> through, a row a species

SAVED/<s> holds a saved run (run.json, cameras.json, scene/lab.glb, or scene/lab.glb.xz to fit
the carry). Each drawn view is written as a run writes it (rgb, labels, depth), so OUT/<s>-*/ are
complete runs that ``agrisim colmap`` reads; ``drawn.json`` says how each was drawn and in how
long. COLMAP runs as ``agrisim colmap RUN`` does (exhaustive matching, the run's intrinsics, the
robot's priors; one thread matches and maps, so several runs at once use the cores).
"""

from __future__ import annotations

import argparse
import json
import lzma
import os
import queue
import shutil
import subprocess
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

PINHOLE = "pinhole"


def _drawn_dirs(out: Path) -> list[Path]:
    return sorted(p.parent for p in out.glob("*/drawn.json"))


def draw_one(saved: Path, out: Path, camera: str | None, imager: str | None, sets: list[str]) -> None:
    """``saved``'s views drawn by Mitsuba (through ``camera`` and shot by ``imager`` where named)
    into the complete run ``out``."""
    from saved_run import drawn_views

    from agrisim.app.arguments import apply_sets
    from agrisim.files import layout
    from agrisim.files.atomic import write_json
    from agrisim.files.dataset import write_frame
    from agrisim.files.rundir import camera_to_json

    overrides: dict = {}
    apply_sets(overrides, sets)
    start = time.perf_counter()
    views = drawn_views(saved, "mitsuba", overrides, camera, imager)
    seconds = time.perf_counter() - start
    out.mkdir(parents=True)
    run = json.loads((saved / layout.RUN_JSON).read_text())
    cameras = json.loads((saved / layout.CAMERAS_JSON).read_text())
    cameras["intrinsics"] = camera_to_json(views[0].camera)
    write_json(out / layout.RUN_JSON, run)
    write_json(out / layout.CAMERAS_JSON, cameras)
    for v in views:
        write_frame(out, v.frame, v.images, None)
    about = {"saved": str(saved), "renderer": "mitsuba", "options": overrides, "camera": camera, "imager": imager}
    write_json(out / "drawn.json", {**about, "views": len(views), "draw_seconds": round(seconds, 1)})


def draw(args: argparse.Namespace) -> None:
    """Every species, pinhole and each ``--through``, a process each, one GPU a process."""
    here = Path(__file__).resolve()
    jobs: queue.Queue[tuple[str, str, list[str]]] = queue.Queue()
    for s in args.species:
        src = args.saved / s / "scene"
        if (src / "lab.glb.xz").is_file() and not (src / "lab.glb").is_file():
            (src / "lab.glb").write_bytes(lzma.decompress((src / "lab.glb.xz").read_bytes()))
        jobs.put((s, PINHOLE, []))
        for lens in args.through:
            camera, imager = lens.split(":")
            jobs.put((s, f"{camera}-{imager}", ["--camera", camera, "--imager", imager]))
    sets = [a for s in args.sets for a in ("--set", s)]
    t0 = time.perf_counter()

    def worker(gpu: int) -> None:
        while True:
            try:
                s, tag, extra = jobs.get_nowait()
            except queue.Empty:
                return
            out = args.out / f"{s}-{tag}"
            if (out / "drawn.json").is_file():
                continue
            shutil.rmtree(out, ignore_errors=True)  # an interrupted draw: drawn again whole
            cmd = [sys.executable, str(here), "draw-one", str(args.saved / s), str(out), *extra, *sets]
            done = subprocess.run(
                cmd, capture_output=True, text=True, env=dict(os.environ, CUDA_VISIBLE_DEVICES=str(gpu))
            )
            status = "ok" if done.returncode == 0 else f"exit {done.returncode}: {done.stderr.strip()[-400:]}"
            print(f"{out.name}: GPU {gpu}, done at {time.perf_counter() - t0:.0f} s, {status}", flush=True)

    threads = [threading.Thread(target=worker, args=(g,)) for g in range(args.gpus)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(f"drawn in {time.perf_counter() - t0:.0f} s on {args.gpus} GPU(s)", flush=True)


def _colmap(run: Path, threads: int) -> tuple[str, float]:
    from agrisim.evaluation.photogrammetry import run_colmap

    start = time.perf_counter()
    run_colmap(run, feature_threads=threads, overwrite=True)
    seconds = time.perf_counter() - start
    (run / "colmap" / "seconds.json").write_text(json.dumps({"colmap_seconds": round(seconds, 1)}) + "\n")
    return run.name, seconds


def colmap(args: argparse.Namespace) -> None:
    """``agrisim colmap``'s pipeline on every drawn run without its poses yet, ``jobs`` at once."""
    todo = [r for r in _drawn_dirs(args.out) if not (r / "colmap" / "seconds.json").is_file()]
    print(f"CPU: {cpu_model()}, {os.cpu_count()} cores; {len(todo)} runs, {args.jobs} at once", flush=True)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        futures = {pool.submit(_colmap, r, args.threads): r for r in todo}
        for f in as_completed(futures):
            try:
                name, seconds = f.result()
                print(f"{name}: COLMAP {seconds:.0f} s, done at {time.perf_counter() - t0:.0f} s", flush=True)
            except Exception as e:  # one run's failure is reported, the others go on
                print(f"{futures[f].name}: failed: {e}", flush=True)


def _cells(run: Path) -> list[str] | None:
    poses = run / "colmap" / "poses.json"
    if not poses.is_file():
        return None
    s = json.loads(poses.read_text())["summary"]

    def pair(name: str, digits: int) -> str:
        med, top = s[f"median_{name}"], s[f"max_{name}"]
        return "-" if med is None else f"{med:.{digits}f} / {top:.{digits}f}"

    reproj = "-" if s["reprojection_px"] is None else f"{s['reprojection_px']:.2f}"
    return [
        f"{s['registered']}",
        f"{s['within_20mm']}",
        pair("centre_error_mm", 1),
        pair("rotation_error_deg", 2),
        reproj,
    ]


def table(args: argparse.Namespace) -> None:
    """A row a species and lens: pinhole -> through, each column."""
    runs = {r.name: r for r in _drawn_dirs(args.out)}
    first = json.loads((next(iter(runs.values())) / "drawn.json").read_text()) if runs else {}
    print(f"Mitsuba {first.get('options') or 'defaults'}, {first.get('views', '?')} views a run; pinhole -> through")
    print(
        "| plant | through | registered | within 20 mm | centre error mm, median / max "
        "| rotation error deg, median / max | reprojection px |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, run in runs.items():
        if not name.endswith(f"-{PINHOLE}"):
            continue
        species = name[: -len(PINHOLE) - 1]
        for other_name, other in runs.items():
            if not other_name.startswith(species + "-") or other == run:
                continue
            tag = other_name[len(species) + 1 :]
            a, b = _cells(run), _cells(other)
            if a is None or b is None:
                continue
            cells = " | ".join(f"{x} -> {y}" for x, y in zip(a, b, strict=True))
            print(f"| {species.replace('_', ' ')} | {tag} | {cells} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    d = sub.add_parser("draw")
    d.add_argument("saved", type=Path)
    d.add_argument("out", type=Path)
    d.add_argument("--through", nargs="+", default=["rpi-camera-3-wide:imx708"], metavar="PRESET:IMAGER")
    d.add_argument("--gpus", type=int, default=1)
    d.add_argument("--species", nargs="+")
    d.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    one = sub.add_parser("draw-one")
    one.add_argument("saved", type=Path)
    one.add_argument("out", type=Path)
    one.add_argument("--camera")
    one.add_argument("--imager")
    one.add_argument("--set", dest="sets", action="append", default=[])
    c = sub.add_parser("colmap")
    c.add_argument("out", type=Path)
    c.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 1) // 3))
    c.add_argument("--threads", type=int, default=3, help="SIFT threads a run")
    t = sub.add_parser("table")
    t.add_argument("out", type=Path)
    args = parser.parse_args()
    if args.command == "draw":
        args.species = args.species or sorted(p.name for p in args.saved.iterdir() if (p / "run.json").is_file())
        draw(args)
    elif args.command == "draw-one":
        draw_one(args.saved, args.out, args.camera, args.imager, args.sets)
    elif args.command == "colmap":
        colmap(args)
    else:
        table(args)


if __name__ == "__main__":
    main()
