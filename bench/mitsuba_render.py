"""The mitsuba renderer measured: image quality of its defaults against a converged reference,
seconds per view, peak memory. Prints figures (with the CPU model); asserts nothing.

* Quality: PSNR and SSIM of the 8-bit sRGB images (what the PNGs hold) at 480x270 against a
  ``--reference-spp`` render (no denoising, long paths) of the same views, for the defaults and
  for raycast (direct light, one shadow sample, ambient), whose gap is what path tracing closes.
* Speed: seconds per view (RGB + labels + depth) at 960x540 and 1920x1080 with the defaults.
* Memory: the process's peak resident set after the 1080p views.

    python bench/mitsuba_render.py [--plant hydrangea] [--views 2] [--reference-spp 1024]
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model  # noqa: E402

from agrisim.config import CellConfig, RenderConfig, RoutineConfig, build_config  # noqa: E402
from agrisim.plant_choice import resolve_plant  # noqa: E402
from agrisim.plugins.render.mitsuba.options import MitsubaOptions  # noqa: E402
from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer  # noqa: E402
from agrisim.plugins.render.raycast import RaycastOptions  # noqa: E402
from agrisim.plugins.render.raycast.renderer import RaycastRenderer  # noqa: E402
from agrisim.plugins.rigs.paper.cell import (
    build_cell,  # noqa: E402
    hemisphere,  # noqa: E402
)
from agrisim.plugins.rooms.lab.room import build_scene  # noqa: E402
from agrisim.registry import Registry, make_plugin_manager  # noqa: E402
from agrisim.robot.kinematics import ArmKinematics  # noqa: E402
from agrisim.scene.camera import preset  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plant", default="hydrangea")
    parser.add_argument("--views", type=int, default=2)
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--skip-speed", action="store_true")
    parser.add_argument("--skip-quality", action="store_true")
    args = parser.parse_args()

    registry = Registry(make_plugin_manager())
    cell = build_cell(CellConfig())
    plant = resolve_plant(registry, build_config({"plant": args.plant, "render": {"labels": "organs"}}))
    scene = build_scene(cell, plant, labels="organs")
    kin = {a.name: ArmKinematics(a) for a in cell.arms}
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    setpoints = hemisphere(cell, RoutineConfig())["r1"]
    views = [setpoints[i].world_T_camera for i in np.linspace(0, len(setpoints) - 1, args.views + 2).astype(int)[1:-1]]
    settings = RenderConfig(labels="organs")
    defaults = MitsubaOptions()
    print(
        f"CPU: {cpu_model()}; plant {args.plant} ({len(plant.mesh.faces):,} triangles); mitsuba defaults: "
        f"{defaults.spp} spp ({defaults.sampler}), {defaults.integrator}, max depth {defaults.max_depth}, denoise {defaults.denoise}"
    )

    if not args.skip_quality:
        quality(scene, cell, settings, views, poses, args.reference_spp)
    if args.skip_speed:
        return
    mitsuba = MitsubaRenderer(scene, cell, settings, defaults)
    for resolution in ("960x540", "1920x1080"):
        cam = preset("rpi3-wide-1080p", resolution)
        mitsuba.render(cam, views[0], poses)  # warm-up at this size
        t0 = time.perf_counter()
        for T in views:
            mitsuba.render(cam, T, poses)
        print(f"mitsuba defaults at {resolution}: {(time.perf_counter() - t0) / len(views):.1f} s/view")
    print(f"peak resident memory: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


def quality(scene, cell, settings, views, poses, reference_spp: int) -> None:  # noqa: ANN001
    """PSNR and SSIM of the 8-bit images against a converged render of the same views."""
    camera = preset("rpi3-wide-1080p", "480x270")
    defaults = MitsubaOptions()
    reference = MitsubaRenderer(
        scene, cell, settings, MitsubaOptions(spp=reference_spp, denoise="off", max_depth=24, seed=99)
    )
    candidates = {
        "mitsuba defaults": MitsubaRenderer(scene, cell, settings, defaults),
        "mitsuba path": MitsubaRenderer(scene, cell, settings, MitsubaOptions(integrator="path")),
        "mitsuba volpath": MitsubaRenderer(scene, cell, settings, MitsubaOptions(integrator="volpath")),
        f"mitsuba {defaults.spp}, raw": MitsubaRenderer(scene, cell, settings, MitsubaOptions(denoise="off")),
        "mitsuba 64 spp": MitsubaRenderer(scene, cell, settings, MitsubaOptions(spp=64)),
        "mitsuba 64, raw": MitsubaRenderer(scene, cell, settings, MitsubaOptions(spp=64, denoise="off")),
        "mitsuba 256, raw": MitsubaRenderer(scene, cell, settings, MitsubaOptions(spp=256, denoise="off")),
        "raycast": RaycastRenderer(scene, cell, settings, RaycastOptions()),
    }
    scores: dict[str, list[tuple[float, float, float]]] = {name: [] for name in candidates}
    for i, T in enumerate(views):
        t0 = time.perf_counter()
        ref = reference.render(camera, T, poses).rgb
        print(f"  view {i}: reference {reference_spp} spp in {time.perf_counter() - t0:.1f} s")
        for name, r in candidates.items():
            r.render(camera, T, poses)  # warm-up (kernels compile on the first view)
            t0 = time.perf_counter()
            img = r.render(camera, T, poses).rgb
            dt = time.perf_counter() - t0
            psnr = peak_signal_noise_ratio(ref, img, data_range=255)
            ssim = structural_similarity(ref, img, channel_axis=2, data_range=255)
            scores[name].append((psnr, ssim, dt))
    print(f"quality at 480x270 against {reference_spp} spp (mean over {len(views)} views):")
    for name, rows in scores.items():
        a = np.array(rows)
        print(f"  {name:18s} PSNR {a[:, 0].mean():5.1f} dB  SSIM {a[:, 1].mean():.3f}  {a[:, 2].mean():6.2f} s/view")


if __name__ == "__main__":
    main()
