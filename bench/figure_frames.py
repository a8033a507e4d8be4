"""Rendered frames for the README (``docs/frames.png``): for three plants, the RGB view, the
paper's texture-based labels and the RepOpa labels (opacity ignored), from the same camera.
Run: ``python bench/figure_frames.py``."""

from __future__ import annotations

import sys
from pathlib import Path

from PIL import Image, ImageDraw

from agrisim.config import RenderConfig

sys.path.insert(0, str(Path(__file__).parent))
from figure_views import figure_views  # noqa: E402

ROWS = [("boxwood", "plant", ("r1", 13)), ("hydrangea", "organs", ("r2", 16)), ("basket_grass", "plant", ("r1", 24))]
W, H = 480, 270


def main(out: Path) -> None:
    views = figure_views(W, H)
    cell, camera, poses = views.cell, views.camera, views.poses
    sheet = Image.new("RGB", (3 * W, len(ROWS) * H), "white")
    draw = ImageDraw.Draw(sheet)
    spec = views.registry.get("renderer", "raycast")
    for row, (name, labels, (robot, index)) in enumerate(ROWS):
        scene = views.scene(name, labels)
        palette = scene.labels.palette()
        T = views.pose(robot, index)
        counts = {}
        for col, mode in enumerate(("texture", "repopa")):
            r = spec.factory(
                scene, cell, RenderConfig(seg_mode=mode, labels=labels), spec.options_model(shadow_samples=8)
            )
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
