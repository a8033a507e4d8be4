"""COLMAP through a real camera, on path-traced views: every species' saved run (scene and
cameras, no images) drawn again by Mitsuba on a GPU, once through the pinhole it was made with
(noise-free) and once through a lens and an imager (each arm's camera auto-exposing from view to
view in capture order), the same draws as the splat table's ``--through`` columns; then
``agrisim colmap``'s pipeline on each, many at once on the CPU cores. Prints figures; asserts
nothing. For a GPU machine of several cores: the draws need Mitsuba (bench/device_site.sh),
COLMAP needs pycolmap (``bench/device_site.sh OUT pycolmap==4.2.1``), so the two stages can be
two calls on one warm machine, each with its own carry::

    python bench/colmap_through.py draw SAVED OUT [--through rpi-camera-3-wide:imx708] [--gpus 4]
        [--species ...] [--set renderer.mitsuba.spp=8 ...]        # OUT/<s>-pinhole/, OUT/<s>-<preset>-<imager>/
    python bench/colmap_through.py develop OUT [--jobs 8]    # after draw --store-noisy (pyoidn)
    python bench/colmap_through.py colmap OUT [--jobs 20] [--threads 3]   # OUT/*/colmap/
    python bench/colmap_through.py table OUT     # Markdown: pinhole -> through, a row a species

SAVED/<s> holds a saved run (run.json, cameras.json, scene/lab.glb, or scene/lab.glb.xz to fit
the carry). Each drawn view is written as a run writes it (rgb, labels, depth), so OUT/<s>-*/ are
complete runs that ``agrisim colmap`` reads; ``drawn.json`` says how each was drawn and in how
long. Mitsuba denoises with OIDN, whose 47 MB (pyoidn) cannot travel beside Mitsuba in one 64
MiB carry: ``draw --store-noisy`` keeps each view's noisy radiance and the denoiser's guides,
and ``develop`` (a call carrying pyoidn) denoises, shoots and writes them, as the renderer
would have (the pinhole's views to 71 dB of a draw that denoised itself: float16 guides). COLMAP runs as ``agrisim colmap RUN`` does (exhaustive matching, the run's intrinsics, the
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

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

from agrisim.plugins.poses.colmap.photogrammetry import PEAK_THRESHOLD  # noqa: E402 (pycolmap is imported when COLMAP runs)

PINHOLE = "pinhole"


def _drawn_dirs(out: Path) -> list[Path]:
    return sorted(p.parent for p in out.glob("*/drawn.json"))


def _recording_denoiser(kept: list[tuple[np.ndarray, ...]]) -> None:
    """Stand pyoidn in for Mitsuba's denoise step, keeping what OIDN would be given (radiance,
    albedo, normal as float16) and passing the noisy radiance on: for a GPU machine where pyoidn
    cannot travel beside Mitsuba, ``develop`` denoises later, as the renderer would have."""
    from agrisim.plugins.render.mitsuba import denoise

    def host(x: object) -> np.ndarray:
        return np.asarray(x.cpu() if hasattr(x, "cpu") else x, np.float16)  # type: ignore[union-attr]

    class Recorder:
        @staticmethod
        def denoise(colour: object, albedo: object, normal: object, hdr: bool = True) -> object:
            kept.append((host(colour), host(albedo), host(normal)))
            return colour

    denoise._pyoidn = lambda: Recorder  # type: ignore[attr-defined]


def draw_one(
    saved: Path, out: Path, camera: str | None, imager: str | None, sets: list[str], store_noisy: bool = False
) -> None:
    """``saved``'s views drawn by Mitsuba (through ``camera`` and shot by ``imager`` where named)
    into the complete run ``out``; with ``store_noisy``, each view's noisy radiance and the
    denoiser's guides go to ``out/noisy/<frame>.npz`` for ``develop`` instead."""
    from saved_run import drawn_views

    from agrisim.files import layout
    from agrisim.files.atomic import write_json
    from agrisim.files.rundir import camera_to_json
    from agrisim.plugins.apps.flags import apply_sets
    from agrisim.plugins.sinks.dataset.writer import write_frame

    overrides: dict = {}
    apply_sets(overrides, sets)
    kept: list[tuple[np.ndarray, ...]] = []
    if store_noisy:
        _recording_denoiser(kept)
        apply_sets(overrides, ["renderer.mitsuba.denoise=on"])
    start = time.perf_counter()
    views = drawn_views(saved, "mitsuba", overrides, camera, None if store_noisy else imager)
    seconds = time.perf_counter() - start
    out.mkdir(parents=True)
    run = json.loads((saved / layout.RUN_JSON).read_text())
    cameras = json.loads((saved / layout.CAMERAS_JSON).read_text())
    cameras["intrinsics"] = camera_to_json(views[0].camera)
    write_json(out / layout.RUN_JSON, run)
    write_json(out / layout.CAMERAS_JSON, cameras)
    for v in views:
        write_frame(out, v.frame, v.images, None)
    if store_noisy:
        assert len(kept) == len(views), f"{len(kept)} denoiser calls for {len(views)} views"
        (out / "noisy").mkdir()
        for v, (colour, albedo, normal) in zip(views, kept, strict=True):
            np.savez(out / "noisy" / f"{v.frame}.npz", colour=colour, albedo=albedo, normal=normal)
    about = {"saved": str(saved), "renderer": "mitsuba", "options": overrides, "camera": camera, "imager": imager}
    order = [v.frame for v in views]
    doc = {
        **about,
        "views": len(views),
        "draw_seconds": round(seconds, 1),
        "order": order,
        "developed": not store_noisy,
    }
    write_json(out / "drawn.json", doc)


def develop(args: argparse.Namespace) -> None:
    """Every drawn run whose views wait in ``noisy/``: denoised by OIDN (pyoidn, guided by the
    albedo and normal, HDR: what the renderer does), then shot by the run's imager (each arm's
    camera auto-exposing in capture order) or, without one, encoded as the renderer encodes
    (exposure 1, clipped, sRGB); the RGB written over the noisy one, ``noisy/`` removed.
    ``jobs`` runs at once."""
    todo = [r for r in _drawn_dirs(args.out) if (r / "noisy").is_dir()]
    print(f"CPU: {cpu_model()}, {os.cpu_count()} cores; {len(todo)} runs to develop, {args.jobs} at once", flush=True)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        for run in pool.map(_develop_run, todo):
            print(f"{run}: developed, done at {time.perf_counter() - t0:.0f} s", flush=True)


def _develop_run(run: Path) -> str:
    from importlib.metadata import version

    import pyoidn

    from agrisim.config import ImagerConfig, build_config
    from agrisim.files import layout
    from agrisim.files.atomic import write_json
    from agrisim.interfaces import Imager, view_key
    from agrisim.plugins.sinks.dataset.writer import write_png
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.scene.colour import encode_srgb8
    from agrisim.validation import open_imager

    doc = json.loads((run / "drawn.json").read_text())
    config = build_config(json.loads((run / layout.RUN_JSON).read_text())["config"])
    settings = ImagerConfig(model=doc["imager"]) if doc["imager"] else None
    shooters: dict[str, Imager | None] = {}
    registry = Registry(make_plugin_manager())
    for frame in doc["order"]:
        noisy = np.load(run / "noisy" / f"{frame}.npz")
        colour, albedo, normal = (np.ascontiguousarray(noisy[k], np.float32) for k in ("colour", "albedo", "normal"))
        radiance = np.asarray(pyoidn.denoise(colour, albedo, normal, hdr=True), np.float32)
        robot = frame.split("_")[0]
        if robot not in shooters:  # each arm's camera its own, auto-exposing from its first view
            shooters[robot] = open_imager(registry, settings, config.seed) if settings is not None else None
        shooter = shooters[robot]
        if shooter is not None:
            rgb = shooter.shoot(radiance, view_key(frame)).rgb
        else:
            h, w = radiance.shape[:2]
            rgb = np.empty((h * w, 3), np.uint8)
            encode_srgb8(np.ascontiguousarray(radiance.reshape(-1, 3)), rgb)
            rgb = rgb.reshape(h, w, 3)
        write_png(layout.image(run, "rgb", frame), rgb)
    write_json(run / "drawn.json", {**doc, "developed": True, "denoiser": f"OIDN (pyoidn {version('pyoidn')})"})
    shutil.rmtree(run / "noisy")
    return run.name


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
    sets = [a for s in args.sets for a in ("--set", s)] + (["--store-noisy"] if args.store_noisy else [])
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


def _colmap(run: Path, threads: int, peak_threshold: float) -> tuple[str, float]:
    from agrisim.plugins.poses.colmap.photogrammetry import run_colmap

    start = time.perf_counter()
    run_colmap(run, feature_threads=threads, peak_threshold=peak_threshold, overwrite=True)
    seconds = time.perf_counter() - start
    (run / "colmap" / "seconds.json").write_text(json.dumps({"colmap_seconds": round(seconds, 1)}) + "\n")
    return run.name, seconds


def colmap(args: argparse.Namespace) -> None:
    """``agrisim colmap``'s pipeline on every drawn run without its poses yet, ``jobs`` at once."""
    todo = [
        r
        for r in _drawn_dirs(args.out)
        if json.loads((r / "drawn.json").read_text()).get("developed", True)
        and not (r / "colmap" / "seconds.json").is_file()
    ]
    print(f"CPU: {cpu_model()}, {os.cpu_count()} cores; {len(todo)} runs, {args.jobs} at once", flush=True)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        futures = {pool.submit(_colmap, r, args.threads, args.peak_threshold): r for r in todo}
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
    d.add_argument(
        "--store-noisy",
        action="store_true",
        help="keep each view's noisy radiance and guides for `develop` (a machine without pyoidn)",
    )
    one = sub.add_parser("draw-one")
    one.add_argument("saved", type=Path)
    one.add_argument("out", type=Path)
    one.add_argument("--camera")
    one.add_argument("--imager")
    one.add_argument("--set", dest="sets", action="append", default=[])
    one.add_argument("--store-noisy", action="store_true")
    dev = sub.add_parser("develop")
    dev.add_argument("out", type=Path)
    dev.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 1) // 8))
    c = sub.add_parser("colmap")
    c.add_argument("out", type=Path)
    c.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 1) // 3))
    c.add_argument("--threads", type=int, default=3, help="SIFT threads a run")
    c.add_argument(
        "--peak-threshold",
        type=float,
        default=PEAK_THRESHOLD,
        help=f"SIFT's contrast threshold (agrisim colmap's default {PEAK_THRESHOLD}; COLMAP's own 0.0067)",
    )
    t = sub.add_parser("table")
    t.add_argument("out", type=Path)
    args = parser.parse_args()
    if args.command == "draw":
        args.species = args.species or sorted(p.name for p in args.saved.iterdir() if (p / "run.json").is_file())
        draw(args)
    elif args.command == "draw-one":
        draw_one(args.saved, args.out, args.camera, args.imager, args.sets, args.store_noisy)
    elif args.command == "develop":
        develop(args)
    elif args.command == "colmap":
        colmap(args)
    else:
        table(args)


if __name__ == "__main__":
    main()
