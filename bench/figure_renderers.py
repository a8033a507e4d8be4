"""The README's renderer comparison (``docs/renderers.png``): the same views drawn by ``raycast``
(direct light, one shadow sample, ambient) and by ``mitsuba`` (path tracing at its defaults),
with the labels both give (byte-identical). Run: ``python bench/figure_renderers.py``."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from agrisim.config import RenderConfig

sys.path.insert(0, str(Path(__file__).parent))
from figure_views import figure_views  # noqa: E402

ROWS = [("hydrangea", "organs", ("r2", 16)), ("indian_cress", "plant", ("r1", 30))]
W, H = 480, 270


def main(out: Path) -> None:
    views = figure_views(W, H)
    cell, camera, poses = views.cell, views.camera, views.poses
    sheet = Image.new("RGB", (3 * W, len(ROWS) * H), "white")
    draw = ImageDraw.Draw(sheet)
    for row, (name, labels, (robot, index)) in enumerate(ROWS):
        scene = views.scene(name, labels)
        T = views.pose(robot, index)
        frames, seconds = {}, {}
        for col, backend in enumerate(("raycast", "mitsuba")):
            spec = views.registry.get("renderer", backend)
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
        spp = views.registry.get("renderer", "mitsuba").options_model().spp
        draw.text((W + 6, row * H + 4), f"mitsuba, {spp} spp denoised: {seconds['mitsuba']:.1f} s", fill="white")
        draw.text((2 * W + 6, row * H + 4), f"{name}: labels ({labels}), identical from both", fill="white")
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/renderers.png"))
