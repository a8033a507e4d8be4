"""What the imager adds to a view: one view of a finished run drawn by ``raycast`` (keeping its
radiance), then shot by each imager preset (auto-exposure, noise, mosaic, demosaicing, colour,
sRGB; and with JPEG), the median of several, in one process. Prints figures; asserts nothing.

    python bench/imager_speed.py RUN [--frame r1_012] [--resolution 1920x1080] [--repeat 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model  # noqa: E402
from saved_run import frame_pose  # noqa: E402

from agrisim.config import RenderConfig  # noqa: E402
from agrisim.files import layout  # noqa: E402
from agrisim.plugins.formats.scene_glb import read_scene  # noqa: E402
from agrisim.plugins.imagers.pipeline import IMAGERS, ImagePipeline  # noqa: E402
from agrisim.plugins.render.raycast import RaycastOptions  # noqa: E402
from agrisim.plugins.render.raycast.renderer import RaycastRenderer  # noqa: E402
from agrisim.scene.camera import preset  # noqa: E402


def median_seconds(work, repeat: int) -> float:  # noqa: ANN001
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        work()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--frame", default="r1_012")
    parser.add_argument("--resolution", default="1920x1080")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    T, poses = frame_pose(args.run_dir, args.frame)
    scene = read_scene(args.run_dir / layout.SCENE_GLB)
    camera = preset("rpi-camera-3-wide", args.resolution)
    renderer = RaycastRenderer(scene, None, RenderConfig(), RaycastOptions(radiance=True))
    frame = renderer.render(camera, T, poses)  # (compiles the kernels)
    render_s = median_seconds(lambda: renderer.render(camera, T, poses), args.repeat)
    assert frame.radiance is not None
    print(f"CPU: {cpu_model()}; {args.resolution} through rpi-camera-3-wide, median of {args.repeat}")
    print(f"raycast view, keeping its radiance: {render_s:.3f} s")
    for name in IMAGERS:
        for quality in (0, 85):
            pipe = ImagePipeline(IMAGERS[name], jpeg_quality=quality)
            pipe.shoot(frame.radiance, 0)
            seconds = median_seconds(lambda p=pipe: p.shoot(frame.radiance, 1), args.repeat)
            jpeg = f", JPEG {quality}" if quality else ""
            print(f"{name}{jpeg}: {seconds:.3f} s a shot ({seconds / render_s:.2f} x the view)")
    renderer.close()


if __name__ == "__main__":
    main()
