"""The rendering of ``agrisim run --renderer mitsuba`` on a GPU machine, from a saved run: per
frame the arms posed, the exact pass (labels, depth, leaf instances) and the path-traced RGB, as
:meth:`MitsubaRenderer.render` gives them to the episode, and every file of the frame written by
one writer thread as the run's DatasetWriter does (:func:`agrisim.plugins.sinks.dataset.writer.write_frame`:
rgb, labels, labels_vis, depth, instances, link poses). What the rest of a run costs (IK,
planning, physics, reconstruction: Pinocchio, OMPL, pybullet, Open3D) is measured on the CPU by
bench/robot_episode.py and bench/recon_views.py. Prints figures; asserts nothing.

    python bench/mitsuba_run_views.py RUN_DIR [--variant cuda] [--frames 100] [--spp 8]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, gpu_name  # noqa: E402
from saved_run import saved_run  # noqa: E402

from agrisim.interfaces import Frame  # noqa: E402
from agrisim.plugins.apps.render import _link_poses  # noqa: E402
from agrisim.plugins.render.mitsuba.options import MitsubaOptions  # noqa: E402
from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer  # noqa: E402
from agrisim.plugins.render.raycast.tracing import label_map  # noqa: E402
from agrisim.plugins.sinks.dataset.writer import write_frame  # noqa: E402
from agrisim.scene.model import LabelTable  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--variant", default="auto")
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--spp", type=int, default=MitsubaOptions().spp)
    args = parser.parse_args()
    saved = saved_run(args.run_dir)
    run, cameras, settings, scene, camera = saved.run, saved.cameras, saved.settings, saved.scene, saved.camera
    palette = LabelTable.from_json(run["labels"]).palette() if run.get("labels") else None
    frames = sorted(cameras["frames"])[: args.frames]
    renderer = MitsubaRenderer(scene, None, settings, MitsubaOptions(variant=args.variant, spp=args.spp))
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}; variant {renderer.mi.variant()}")
    print(
        f"{camera.width}x{camera.height}, {len(frames)} frames, {args.spp} spp, denoise "
        f"{'on' if renderer.denoise else 'off (no pyoidn)'}; labels {settings.labels}, {settings.seg_mode}"
    )
    exact = rgb = wait = 0.0
    with tempfile.TemporaryDirectory() as out, ThreadPoolExecutor(1) as writer:
        pending: list[Future[None]] = []
        t_start = t_after_first = time.perf_counter()
        first = 0.0
        for i, f in enumerate(frames):
            T = np.asarray(cameras["frames"][f]["world_T_camera"], np.float64)
            poses = _link_poses(args.run_dir, f)
            t0 = time.perf_counter()
            tracer = renderer.tracer
            tracer.place_arms(poses, (camera, T))
            images = tracer.exact(camera, T, seg_mode=settings.seg_mode, label_map=label_map(settings.labels))
            t1 = time.perf_counter()
            colour, _ = renderer.render_rgb(camera, T, poses)
            t2 = time.perf_counter()
            frame = Frame(rgb=colour, labels=images["labels"], depth=images["depth"], instances=images.get("instances"))
            while pending and (pending[0].done() or len(pending) > 2):  # as the run's writer: a few queued
                pending.pop(0).result()
            t3 = time.perf_counter()
            pending.append(writer.submit(write_frame, Path(out), f, frame, palette, poses, settings.depth_format))
            if i == 0:
                first = time.perf_counter() - t_start
                t_after_first = time.perf_counter()
            else:
                exact, rgb, wait = exact + t1 - t0, rgb + t2 - t1, wait + t3 - t2
        for p in pending:
            p.result()
        total = time.perf_counter() - t_after_first
    n = max(len(frames) - 1, 1)
    print(
        f"first frame {first:.2f} s (kernels compile); then {n / total:.2f} views/s ({1e3 * total / n:.0f} ms a view, "
        f"files written): exact pass {1e3 * exact / n:.1f} ms, RGB {1e3 * rgb / n:.1f} ms, waiting for the writer "
        f"{1e3 * wait / n:.1f} ms"
    )
    renderer.close()


if __name__ == "__main__":
    main()
