"""The raycast renderer of two checkouts on the same views: labels, depth and RGB compared view by
view. Prints figures; asserts nothing.

Each checkout renders in its own environment (``make setup`` in it) into a file of images; this
script then compares them: labels (share of equal pixels), depth (pixels where both see something
and differ by more than 1e-5 m) and RGB PSNR. With shadow samples the RGB of one image carries
its sampling noise, so two renderers whose random streams differ cannot agree better than one
renderer with two seeds: ``--seeds K`` renders K seeds on each side and compares the means
(PSNR of the before mean against the after mean, beside that of the before mean of K seeds
against the before mean of K others: the noise floor).

    python bench/engine_agreement.py ../before . [--plants indian_cress ...] [--resolution 1920x1080]
        [--shadow-samples 0 1] [--seeds 8] [--figure docs/engine_agreement.png]

``--figure`` draws the pixels whose labels differ, up to six, each as a close-up of the RGB with
the labels before and after beside it.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model  # noqa: E402

WORKER = r"""
import sys, numpy as np
from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.rooms.lab.room import build_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.kinematics import ArmKinematics
from agrisim.plugins.rigs.paper.cell import hemisphere
from agrisim.scene.camera import preset
from agrisim.plugins.rigs.paper.cell import build_cell
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.renderer import RaycastRenderer
plant, resolution, samples, seeds, seg_mode, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), [int(s) for s in sys.argv[4].split(",")], sys.argv[5], sys.argv[6]
registry = Registry(make_plugin_manager())
cell = build_cell(CellConfig())
scene = build_scene(cell, resolve_plant(registry, build_config({"plant": plant})))
camera = preset("rpi3-wide-1080p", resolution)
kin = {a.name: ArmKinematics(a) for a in cell.arms}
poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
sp = hemisphere(cell, RoutineConfig())
views = [sp["r1"][i].world_T_camera for i in (0, 20, 40)] + [sp["r2"][i].world_T_camera for i in (5, 30)]
images = {}
for seed in seeds:
    r = RaycastRenderer(scene, cell, RenderConfig(seg_mode=seg_mode), RaycastOptions(shadow_samples=samples, seed=seed))
    for k, T in enumerate(views):
        f = r.render(camera, T, poses)
        images[f"rgb_{seed}_{k}"] = f.rgb
        if seed == seeds[0]:
            images[f"labels_{k}"], images[f"depth_{k}"] = f.labels, f.depth
    r.close()
np.savez(out, **images)
"""


def render(
    checkout: Path, plant: str, resolution: str, samples: int, seeds: list[int], seg_mode: str, out: Path
) -> dict:
    python = checkout / ".venv" / "bin" / "python"
    if not python.exists():
        raise SystemExit(f"{checkout} has no .venv: run `make setup` there first")
    args = [str(python), "-c", WORKER, plant, resolution, str(samples), ",".join(map(str, seeds)), seg_mode, str(out)]
    subprocess.run(args, cwd=checkout, check=True, stdout=subprocess.DEVNULL)
    return dict(np.load(out))


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(((a.astype(np.float64) - b) ** 2).mean())
    return 10 * np.log10(255.0**2 / mse) if mse > 0 else float("inf")


def figure(path: Path, found: list[tuple[str, int, np.ndarray, np.ndarray, np.ndarray, int, int]]) -> None:
    """Close-ups (RGB, labels before, labels after) of pixels whose labels differ, the pixel
    outlined in magenta."""
    from PIL import Image, ImageDraw

    half, zoom = 10, 8
    palette = np.random.default_rng(0).integers(40, 255, (256, 3)).astype(np.uint8)
    palette[0] = 0
    rows = []
    for _, _, rgb, lab_b, lab_a, y, x in found[:6]:
        y0, x0 = max(0, y - half), max(0, x - half)
        crops = [
            rgb[y0 : y + half + 1, x0 : x + half + 1],
            palette[lab_b[y0 : y + half + 1, x0 : x + half + 1]],
            palette[lab_a[y0 : y + half + 1, x0 : x + half + 1]],
        ]
        tiles = []
        for c in crops:
            img = Image.fromarray(np.ascontiguousarray(c)).resize((c.shape[1] * zoom, c.shape[0] * zoom), Image.NEAREST)
            ImageDraw.Draw(img).rectangle(
                [(x - x0) * zoom, (y - y0) * zoom, (x - x0 + 1) * zoom - 1, (y - y0 + 1) * zoom - 1],
                outline=(255, 0, 255),
                width=2,
            )
            tiles.append(np.asarray(img))
        h = max(t.shape[0] for t in tiles)
        rows.append(
            np.concatenate([np.pad(t, ((0, h - t.shape[0]), (0, 4), (0, 0)), constant_values=255) for t in tiles], 1)
        )
    if not rows:
        print(f"no label differs: {path} not drawn")
        return
    w = max(r.shape[1] for r in rows)
    grid = np.concatenate([np.pad(r, ((0, 4), (0, w - r.shape[1]), (0, 0)), constant_values=255) for r in rows], 0)
    Image.fromarray(grid).save(path)
    print(f"{path}: {len(rows)} close-ups: " + ", ".join(f"{p} view {v} ({y}, {x})" for p, v, *_, y, x in found[:6]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--plants", nargs="+", default=["indian_cress"])
    parser.add_argument("--resolution", default="1920x1080")
    parser.add_argument("--shadow-samples", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--seeds", type=int, default=1, help="seeds per side for the means (with shadow samples)")
    parser.add_argument("--seg-mode", default="texture", choices=["texture", "repopa"])
    parser.add_argument("--figure", type=Path, default=None, help="draw close-ups of pixels whose labels differ")
    args = parser.parse_args()
    found = []
    print(
        f"{cpu_model()}; before {args.before}, after {args.after}; {args.resolution}, 5 views a plant, {args.seg_mode} labels"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for plant in args.plants:
            for samples in args.shadow_samples:
                k = args.seeds if samples else 1
                seeds = list(range(k))
                b = render(
                    args.before,
                    plant,
                    args.resolution,
                    samples,
                    seeds + [s + 1000 for s in seeds] if samples and k > 1 else seeds,
                    args.seg_mode,
                    Path(tmp) / "b.npz",
                )
                a = render(args.after, plant, args.resolution, samples, seeds, args.seg_mode, Path(tmp) / "a.npz")
                rows = []
                for v in range(5):
                    lab = float((a[f"labels_{v}"] == b[f"labels_{v}"]).mean())
                    if samples == args.shadow_samples[0]:
                        for y, x in zip(*np.nonzero(a[f"labels_{v}"] != b[f"labels_{v}"]), strict=True):
                            found.append(
                                (plant, v, a[f"rgb_0_{v}"], b[f"labels_{v}"], a[f"labels_{v}"], int(y), int(x))
                            )
                    da, db = a[f"depth_{v}"], b[f"depth_{v}"]
                    both = (da > 0) & (db > 0)
                    far = int((both & (np.abs(da - db) > 1e-5)).sum())
                    mean_a = np.mean([a[f"rgb_{s}_{v}"] for s in seeds], axis=0)
                    mean_b = np.mean([b[f"rgb_{s}_{v}"] for s in seeds], axis=0)
                    row = f"labels {100 * lab:.4f}%, depth > 1e-5 m on {far} px, RGB PSNR {psnr(mean_a, mean_b):.1f} dB"
                    if samples and k > 1:
                        other = np.mean([b[f"rgb_{s + 1000}_{v}"] for s in seeds], axis=0)
                        row += f" (before against itself, other seeds: {psnr(other, mean_b):.1f} dB)"
                    rows.append(row)
                what = f"mean of {k} seeds" if samples and k > 1 else "one seed"
                print(f"{plant}, {samples} shadow sample(s), {what}:")
                for v, row in enumerate(rows):
                    print(f"  view {v}: {row}")
    if args.figure is not None:
        figure(args.figure, found)


if __name__ == "__main__":
    main()
