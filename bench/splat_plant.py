"""Which training choices hold the plant: the ``splat`` reconstructor trained once per variant on
the same views, each variant's figures printed side by side. Prints figures; asserts nothing.

For a GPU machine with the minimal install (bench/device_install.sh with gsplat). The views come
either from a run on disk, or are drawn there from a saved run's scene (``--draw``, Mitsuba in the
install too): RGB, labels and depth all by the renderer's own full pass (exact labels and depth,
the run's), so that the carry holds the scene and cameras but no images::

    python bench/splat_plant.py train RUN --draw raycast --set renderer.raycast.shadow_samples=32 \
        --variant base --variant depth:depth_weight=1 --variant plant:plant_weight=5,plant_init=0.5 \
        [--out DIR] [--files VARIANT]
    python bench/splat_plant.py train RUN --draw mitsuba --camera rpi-camera-3-wide --imager imx708 ...
    python bench/splat_plant.py pack RUN CARRY   # on the CPU: RUN's views with lossless WebP RGB

Each variant is ``NAME[:KEY=VALUE,...]`` of ``[recon.splat]`` options over the defaults. With
``--out``, DIR/<name>.json holds each variant's metrics, and DIR/<name>/ the figures of those
named by ``--files`` (heldout.jpg: the held-out view with the most plant, truth | splats | error,
whole and the plant close up; worst.jpg: the held-out view of the lowest PSNR). ``pack`` copies a run's cameras and labels,
stores its RGB as lossless WebP (0.33 against 0.54 MB a 960x540 view) and its depth as xz'd
row differences (0.09 against 0.16 MB): 100 views then travel beside gsplat in one 64 MiB carry.
"""

from __future__ import annotations

import argparse
import io
import json
import lzma
import shutil
import sys
from pathlib import Path

import numpy as np
from PIL import Image

from agrisim.evaluation.views import load_depth
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json, capture_order
from agrisim.interfaces import Frame, View
from agrisim.plugins.apps.flags import apply_sets, parse_value
from agrisim.plugins.poses.colmap.photogrammetry import estimated_poses
from agrisim.plugins.recon.splat.options import SplatOptions
from agrisim.plugins.recon.splat.reconstructor import SplatReconstructor
from agrisim.scene.encoding import mm_to_depth
from agrisim.scene.model import LabelTable

sys.path.insert(0, str(Path(__file__).resolve().parent))
from saved_run import drawn_views  # noqa: E402


def variant(text: str) -> tuple[str, dict[str, object]]:
    name, _, rest = text.partition(":")
    options: dict[str, object] = {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        options[key] = parse_value(value)
    SplatOptions(**options)  # refused here, before anything is rendered
    return name, options


def stored_views(run: Path, poses: str = "truth") -> list[View]:
    """The run's views as stored, in capture order (as ``agrisim recon`` takes them), its RGB
    from PNG or (a packed carry) WebP; with ``poses = "colmap"`` only the views COLMAP placed,
    at its poses (``agrisim colmap``'s poses.json)."""
    cameras = json.loads((run / layout.CAMERAS_JSON).read_text())
    camera = camera_from_json(cameras["intrinsics"])
    if poses == "colmap":
        at = estimated_poses(run)
    else:
        at = {f: np.asarray(d["world_T_camera"], np.float64) for f, d in cameras["frames"].items()}
    views = []
    for frame in capture_order(json.loads((run / layout.RUN_JSON).read_text()), at):
        webp = run / "rgb" / f"{frame}.webp"
        rgb = np.asarray(Image.open(webp if webp.is_file() else layout.image(run, "rgb", frame)).convert("RGB"))
        labels = np.asarray(Image.open(layout.image(run, "labels", frame)))
        packed = run / "depth" / f"{frame}.npy.xz"
        if packed.is_file():
            rows = np.load(io.BytesIO(lzma.decompress(packed.read_bytes())))
            depth = mm_to_depth(np.cumsum(rows, axis=1, dtype=np.int32).astype(np.uint16))
        else:
            depth = load_depth(run, frame)
        views.append(View(frame, camera, at[frame], Frame(rgb, labels, depth)))
    return views


def pack(run: Path, carry: Path) -> None:
    if carry.exists():
        raise SystemExit(f"{carry} exists")
    (carry / "rgb").mkdir(parents=True)
    for name in (layout.RUN_JSON, layout.CAMERAS_JSON):
        shutil.copy2(run / name, carry / name)
    shutil.copytree(run / "labels", carry / "labels")
    if (run / layout.COLMAP / "poses.json").is_file():
        (carry / layout.COLMAP).mkdir()
        shutil.copy2(run / layout.COLMAP / "poses.json", carry / layout.COLMAP / "poses.json")
    (carry / "depth").mkdir()
    for png in sorted((run / "depth").glob("*.png")):  # row differences, xz: 0.09 against 0.16 MB a view
        mm = np.asarray(Image.open(png)).astype(np.int32)
        buf = io.BytesIO()
        np.save(buf, np.diff(mm, axis=1, prepend=0).astype(np.int16))
        (carry / "depth" / f"{png.stem}.npy.xz").write_bytes(lzma.compress(buf.getvalue(), preset=9))
    for png in sorted((run / "rgb").glob("*.png")):  # method 4: 0.8 s a view; 6 saves 2% more in 7.6 s
        Image.open(png).save(carry / "rgb" / f"{png.stem}.webp", lossless=True, quality=100, method=4)
    size = sum(p.stat().st_size for p in carry.rglob("*") if p.is_file()) / 1e6
    print(f"{carry}: {size:.1f} MB")


def figures(views: list[View], files: dict[str, bytes], metrics: dict, folder: Path) -> None:
    """``heldout.jpg``: the held-out view with the most plant, truth | splats | error in full and
    the plant close up; ``worst.jpg``: the held-out view of the lowest PSNR, in full."""
    folder.mkdir(parents=True, exist_ok=True)
    by_frame = {v.frame: v for v in views}
    rows = metrics["views"]
    best = max(rows, key=lambda r: r["plant_pixels"])["frame"]
    worst = min(rows, key=lambda r: r["psnr"])["frame"]

    def panel(frame: str) -> np.ndarray:
        return np.asarray(Image.open(io.BytesIO(files[f"splat/test/{frame}.png"])).convert("RGB"))

    Image.fromarray(panel(worst)).save(folder / "worst.jpg", quality=90)
    whole = panel(best)
    w = whole.shape[1] // 3
    parts = [whole[:, i * w : (i + 1) * w] for i in range(3)]
    ys, xs = np.nonzero(by_frame[best].images.labels != 0)
    pad = 12
    y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, whole.shape[0])
    x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, w)
    half = [Image.fromarray(p).resize((w // 2, whole.shape[0] // 2), Image.Resampling.LANCZOS) for p in parts]
    scale = (w // 2) / (x1 - x0)
    size = (w // 2, round((y1 - y0) * scale))
    close = [Image.fromarray(p[y0:y1, x0:x1]).resize(size, Image.Resampling.NEAREST) for p in parts]
    out = Image.new("RGB", (3 * (w // 2), half[0].height + size[1]))
    for i, (h, c) in enumerate(zip(half, close, strict=True)):
        out.paste(h, (i * (w // 2), 0))
        out.paste(c, (i * (w // 2), h.height))
    out.save(folder / "heldout.jpg", quality=92)


def train(args: argparse.Namespace) -> None:
    overrides: dict = {}
    apply_sets(overrides, args.sets)
    for poses in args.poses:
        if args.draw and poses != "truth":
            raise SystemExit("--draw draws the views at their true poses only")
        if (args.camera or args.imager) and not args.draw:
            raise SystemExit("--camera and --imager apply to views drawn here (--draw)")
        views = (
            drawn_views(args.run, args.draw, overrides, args.camera, args.imager)
            if args.draw
            else stored_views(args.run, poses)
        )
        plant_share = np.mean([np.mean(v.images.labels != 0) for v in views])
        print(f"{poses} poses: {len(views)} views; plant pixels {100 * plant_share:.1f}% of the image", flush=True)
        variants = [(f"{n}-{poses}" if len(args.poses) > 1 else n, o) for n, o in args.variants]
        about = {"poses": poses, "draw": args.draw, "render_options": overrides, "camera": args.camera}
        train_variants(args, views, variants, {**about, "imager": args.imager})


def train_variants(args: argparse.Namespace, views: list[View], variants: list[tuple[str, dict]], about: dict) -> None:
    labels = LabelTable.from_json(json.loads((args.run / layout.RUN_JSON).read_text())["labels"])
    for name, options in variants:
        rec = SplatReconstructor(labels, SplatOptions(**options))
        for v in views:
            rec.integrate(v)
        result = rec.result()
        m = result.metrics
        g = m["geometry"]
        print(
            f"{name:>12} {json.dumps(options)}: PSNR {m['psnr']:.2f} dB, SSIM {m['ssim']:.3f}, plant PSNR "
            f"{m['psnr_plant']:.2f} dB, plant depth error median {m['depth_error_mm']['median']:.1f} mm, plant "
            f"centres precision/recall@2mm {g['precision@2mm']:.3f}/{g['recall@2mm']:.3f} "
            f"({g['plant_gaussians']:,} of {m['gaussians']:,} Gaussians), {m['train_seconds']:.0f} s",
            flush=True,
        )
        if args.out is not None:
            args.out.mkdir(parents=True, exist_ok=True)
            doc = {"options": options, **about, "splat": m}
            (args.out / f"{name}.json").write_text(json.dumps(doc, indent=1) + "\n")
            if name in args.files:
                figures(views, result.files, m, args.out / name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train")
    t.add_argument("run", type=Path)
    t.add_argument("--draw", metavar="RENDERER", help="draw the views from the run's scene with this renderer")
    t.add_argument("--set", dest="sets", action="append", default=[], help="renderer.* KEY=VALUE for --draw")
    t.add_argument("--camera", metavar="PRESET", help="with --draw: through this camera preset, not the run's")
    t.add_argument("--imager", metavar="NAME", help="with --draw: shot by this imager (auto-exposure), not the run's")
    t.add_argument("--variant", dest="variants", action="append", type=variant, required=True)
    t.add_argument("--out", type=Path)
    t.add_argument("--poses", nargs="+", choices=["truth", "colmap"], default=["truth"], help="train on these poses")
    t.add_argument("--files", action="append", default=[], help="variants whose files are kept")
    p = sub.add_parser("pack")
    p.add_argument("run", type=Path)
    p.add_argument("carry", type=Path)
    args = parser.parse_args()
    if args.command == "pack":
        pack(args.run, args.carry)
    else:
        train(args)


if __name__ == "__main__":
    main()
