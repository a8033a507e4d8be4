"""Rendered frames for the README (``docs/frames.png``): for three plants, the RGB view, the
paper's texture-based labels and the RepOpa labels (opacity ignored), from the same camera.
Run: ``python bench/figure_frames.py``."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from agrisim.scene.camera import preset
from agrisim.scene.cell import build_cell
from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config
from agrisim.episode import resolve_plant
from agrisim.robot.kinematics import ArmKinematics
from agrisim.lab.room import build_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.setpoints import hemisphere

ROWS = [("boxwood", "plant", ("r1", 13)), ("hydrangea", "organs", ("r2", 16)), ("basket_grass", "plant", ("r1", 24))]
W, H = 480, 270


def main(out: Path) -> None:
    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    kin = {a.name: ArmKinematics(a) for a in cell.arms}
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    camera = preset("rpi3-wide-1080p", f"{W}x{H}")
    sps = hemisphere(cell, RoutineConfig())
    sheet = Image.new("RGB", (3 * W, len(ROWS) * H), "white")
    draw = ImageDraw.Draw(sheet)
    spec = registry.get("renderer", "raycast")
    for row, (name, labels, (robot, index)) in enumerate(ROWS):
        scene = build_scene(cell, resolve_plant(registry, build_config({"plant": name})), labels=labels)
        palette = scene.labels.palette()
        T = sps[robot][index].world_T_camera
        counts = {}
        for col, mode in enumerate(("texture", "repopa")):
            r = spec.factory(scene, cell, RenderConfig(seg_mode=mode, labels=labels), spec.options_model(shadow_samples=8))
            frame = r.render(camera, T, poses)
            r.close()
            if col == 0:
                sheet.paste(Image.fromarray(frame.rgb), (0, row * H))
            sheet.paste(Image.fromarray(palette[frame.labels]), ((col + 1) * W, row * H))
            counts[mode] = int((frame.labels > 0).sum())
        more = 100 * (counts["repopa"] / counts["texture"] - 1)
        draw.text((6, row * H + 4), f"{name} (RGB)", fill="white")
        draw.text((W + 6, row * H + 4), f"texture labels ({labels}): {counts['texture']:,} px", fill="white")
        draw.text((2 * W + 6, row * H + 4), f"RepOpa labels: {counts['repopa']:,} px (+{more:.0f}%)", fill="white")
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/frames.png"))
