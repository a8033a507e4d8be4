"""The README's renderer comparison (``docs/renderers.png``): the same views drawn by ``raycast``
(direct light, one shadow sample, ambient) and by ``mitsuba`` (path tracing at its defaults),
with the labels both give (byte-identical). Run: ``python bench/figure_renderers.py``."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config
from agrisim.lab.room import build_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.setpoints import hemisphere
from agrisim.scene.camera import preset
from agrisim.scene.cell import build_cell
from agrisim.scene.plant_choice import resolve_plant

ROWS = [("hydrangea", "organs", ("r2", 16)), ("indian_cress", "plant", ("r1", 30))]
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
    for row, (name, labels, (robot, index)) in enumerate(ROWS):
        scene = build_scene(cell, resolve_plant(registry, build_config({"plant": name})), labels=labels)
        T = sps[robot][index].world_T_camera
        frames, seconds = {}, {}
        for col, backend in enumerate(("raycast", "mitsuba")):
            spec = registry.get("renderer", backend)
            r = spec.factory(scene, cell, RenderConfig(labels=labels), spec.options_model())
            r.render(camera, T, poses)  # warm-up (Mitsuba compiles its kernels on the first view)
            t0 = time.perf_counter()
            frames[backend] = r.render(camera, T, poses)
            seconds[backend] = time.perf_counter() - t0
            r.close()
            sheet.paste(Image.fromarray(frames[backend].rgb), (col * W, row * H))
        assert np.array_equal(frames["raycast"].labels, frames["mitsuba"].labels)
        sheet.paste(Image.fromarray(scene.labels.palette()[frames["mitsuba"].labels]), (2 * W, row * H))
        draw.text((6, row * H + 4), f"raycast: {seconds['raycast']:.2f} s", fill="white")
        draw.text((W + 6, row * H + 4), f"mitsuba, 16 spp denoised: {seconds['mitsuba']:.1f} s", fill="white")
        draw.text((2 * W + 6, row * H + 4), f"{name}: labels ({labels}), identical from both", fill="white")
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/renderers.png"))
