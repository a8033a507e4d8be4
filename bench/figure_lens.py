"""The README's lens figure (``docs/lens.png``): one view of a finished run re-rendered by
``raycast`` through the paper's pinhole (``rpi3-wide-1080p``, 99.1 degrees) and through the
Camera Module 3 Wide's lens (``rpi-camera-3-wide``, 102 degrees: the same sensor and focal
length, its barrel distortion bending the table's straight edges), each with its labels.

    python bench/figure_lens.py RUN_DIR [--frame r1_012] [--resolution 960x540]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from saved_run import frame_pose  # noqa: E402

from agrisim.config import RenderConfig  # noqa: E402
from agrisim.files import layout  # noqa: E402
from agrisim.plugins.formats.scene_glb import read_scene  # noqa: E402
from agrisim.plugins.render.raycast import RaycastOptions  # noqa: E402
from agrisim.plugins.render.raycast.renderer import RaycastRenderer  # noqa: E402
from agrisim.scene.camera import preset  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--frame", default="r1_012")
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--out", type=Path, default=Path("docs/lens.png"))
    args = parser.parse_args()

    T, poses = frame_pose(args.run_dir, args.frame)
    renderer = RaycastRenderer(
        read_scene(args.run_dir / layout.SCENE_GLB),
        None,
        RenderConfig(),
        RaycastOptions(shadow_samples=4, supersample=2),
    )
    rows = []
    for name in ("rpi3-wide-1080p", "rpi-camera-3-wide"):
        camera = preset(name, args.resolution)
        frame = renderer.render(camera, T, poses)
        rows.append((name, camera, frame))

    fig, axes = plt.subplots(2, 2, figsize=(10, 5.8), dpi=90)
    for (name, camera, frame), (ax_rgb, ax_labels) in zip(rows, axes, strict=True):
        ax_rgb.imshow(frame.rgb)
        ax_rgb.set_title(f"{name}: {camera.hfov_deg:.1f} degrees horizontal")
        ax_labels.imshow(frame.labels > 0, cmap="Greens")
        ax_labels.set_title("labels, exact at each pixel's own ray")
        for ax in (ax_rgb, ax_labels):
            ax.set_xlim(-0.5, camera.width - 0.5)
            ax.set_ylim(camera.height - 0.5, -0.5)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
