"""The README's plant figures: every procedural species close up, in the lab, one row a species
and one column a plant seed (``--seeds 0 1 2 3``: four individuals), drawn by a renderer at its
defaults; ``--leaf`` adds a macro view of one leaf of each species; ``--before SHEET`` puts a
one-column sheet this script made in another checkout (the plants as they were) on the left.
Prints the CPU model and seconds; writes one PNG.

    python bench/figure_species.py docs/species.png [--renderer mitsuba] [--seeds 0 1 2 3]
        [--size 480x360] [--distance 0.42] [--species boston_fern ...] [--leaf] [--before PNG]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from agrisim.config import RenderConfig, build_config
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.plants.procedural.species import SPECIES
from agrisim.plugins.rooms.lab.room import build_scene
from agrisim.robot.cell import soil_pose
from agrisim.scene.camera import from_fov
from agrisim.scene.texturing import label_at
from agrisim.scene.transforms import look_at

sys.path.insert(0, str(Path(__file__).parent))
from figure_views import figure_views  # noqa: E402
from machine import cpu_model  # noqa: E402


def leaf_target(plant, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """(centre, upper-side normal) of one of the plant's larger, higher leaves, in its frame: a
    leaf instance whose texels are labelled leaf."""
    mesh = plant.mesh
    leaf_id = plant.labels.by_name("leaf").id
    tri = mesh.vertices[mesh.faces]
    centre = tri.mean(axis=1)
    uv = mesh.uvs[mesh.faces].mean(axis=1) if mesh.uvs is not None else np.zeros((len(mesh.faces), 2))
    is_leaf = np.zeros(len(mesh.faces), bool)
    for i, material in enumerate(mesh.materials):
        sel = mesh.face_material == i
        is_leaf[sel] = label_at(material, uv[sel]) == leaf_id
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    instances = mesh.face_instance if mesh.face_instance is not None else np.zeros(len(mesh.faces), int)
    best = []
    for i in np.unique(instances[is_leaf & (instances > 0)]):
        sel = instances == i
        reach = np.hypot(*centre[sel, :2].mean(axis=0))  # outer leaves: nothing above them
        best.append((area[sel].sum() * (1.0 + reach / 0.1), i))
    best.sort(reverse=True)
    chosen = best[int(rng.integers(0, max(1, len(best) // 4)))][1] if best else 0
    sel = (instances == chosen) & is_leaf
    normal = np.cross(tri[sel, 1] - tri[sel, 0], tri[sel, 2] - tri[sel, 0]).sum(axis=0)
    normal /= max(np.linalg.norm(normal), 1e-12)
    return np.average(centre[sel], axis=0, weights=area[sel]), normal


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--renderer", default="mitsuba")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--size", default="480x360")
    parser.add_argument("--distance", type=float, default=0.62, help="camera to plant centre, m")
    parser.add_argument("--fov", type=float, default=50.0, help="horizontal field of view, degrees")
    parser.add_argument("--species", nargs="+", default=list(SPECIES))
    parser.add_argument("--leaf", action="store_true", help="add a column: one leaf from 0.12 m with a 40° lens")
    parser.add_argument("--before", type=Path, help="a one-column sheet of another checkout, put on the left")
    args = parser.parse_args()
    views = figure_views(64, 64)
    width, height = (int(v) for v in args.size.split("x"))
    camera = from_fov(args.fov, width, height)
    W, H = camera.width, camera.height
    before = int(args.before is not None)
    cols = before + len(args.seeds) + int(args.leaf)
    sheet = Image.new("RGB", (cols * W, len(args.species) * H), "white")
    draw = ImageDraw.Draw(sheet)
    spec = views.registry.get("renderer", args.renderer)
    print(f"CPU: {cpu_model()}; renderer {args.renderer}, {W}x{H}")
    soil = soil_pose(views.cell)
    if args.before is not None:
        old = Image.open(args.before).convert("RGB")
        if old.size != (W, len(args.species) * H):
            raise SystemExit(f"--before: {args.before} is {old.size[0]}x{old.size[1]}, not one column of these rows")
        sheet.paste(old, (0, 0))
        for row in range(len(args.species)):
            draw.rectangle((0, row * H, W, row * H + 16), fill=(40, 40, 40))
            draw.text((6, row * H + 3), f"{args.species[row]}: before", fill="white")
    for row, name in enumerate(args.species):
        for col, seed in enumerate(args.seeds):
            t0 = time.perf_counter()
            plant = resolve_plant(views.registry, build_config({"plant": name, "seed": seed}))
            scene = build_scene(views.cell, plant)
            # from the side the lamps are not on (they stand by the arms, along x), 35 degrees up
            target = soil[:3, 3] + np.array([0.0, 0.0, 0.13])
            az, up = np.radians(100.0 + 25 * col), np.radians(35.0)
            eye = target + args.distance * np.array([np.cos(az) * np.cos(up), np.sin(az) * np.cos(up), np.sin(up)])
            r = spec.factory(scene, views.cell, RenderConfig(), spec.options_model())
            frame = r.render(camera, look_at(eye, target), views.poses)
            if args.leaf and col == 0:
                leaf, normal = leaf_target(plant, np.random.default_rng(seed))
                leaf = soil[:3, :3] @ leaf + soil[:3, 3]
                side = np.cross(normal, [0.0, 0.0, 1.0]) if abs(normal[2]) < 0.99 else np.array([1.0, 0, 0])
                eye_leaf = leaf + 0.12 * (0.85 * normal + 0.5 * side / max(np.linalg.norm(side), 1e-9))
                macro = r.render(from_fov(40.0, W, H), look_at(eye_leaf, leaf), views.poses)
                x = (before + len(args.seeds)) * W
                sheet.paste(Image.fromarray(macro.rgb), (x, row * H))
                draw.text((x + 6, row * H + 4), f"{name}: a leaf from 0.12 m (40° lens)", fill="white")
            r.close()
            sheet.paste(Image.fromarray(frame.rgb), ((before + col) * W, row * H))
            draw.text(((before + col) * W + 6, row * H + 4), f"{name}, seed {seed}", fill="white")
            print(f"{name} seed {seed}: {time.perf_counter() - t0:.1f} s, {len(plant.mesh.faces):,} triangles")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out, quality=88, optimize=True)  # (JPEG options; a .png ignores them)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
