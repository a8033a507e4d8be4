"""``agrisim render`` on an NVIDIA GPU (Mitsuba's ``cuda_ad_rgb``, OptiX). Marked ``gpu``: CI has
no GPU and skips it (tests/conftest.py); it runs on the project's GPU machine from a minimal
install (no Open3D, pybullet, Pinocchio, OMPL or Rerun there), with ``--noconftest``, together
with the camera and light tests of tests/unit/test_mitsuba_optics.py (``-m gpu``).

Truth: the CPU (LLVM) variant's image of the same saved frames.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.gpu


@pytest.mark.skipif(not os.environ.get("AGRISIM_GPU_RUN"), reason="AGRISIM_GPU_RUN names no saved run")
def test_rerender_on_the_gpu_matches_the_cpu_variant(tmp_path: Path) -> None:
    """``agrisim render`` of a saved run on CUDA: labels and depth are the run's own, and the RGB
    of each frame agrees with the CPU variant's (same scene and settings, 4 samples per pixel,
    other noise) to a few percent of mean brightness."""
    import subprocess
    import sys

    run = Path(os.environ["AGRISIM_GPU_RUN"])
    means = {}
    for variant in ("cuda", "llvm"):
        code = (
            "from agrisim.app.cli import main; import sys; "
            f"sys.exit(main(['render', {str(run)!r}, '--out', {str(tmp_path / variant)!r}, "
            f"'--set', 'renderer.mitsuba.variant={variant}', '--set', 'renderer.mitsuba.spp=4', '--set', 'renderer.mitsuba.denoise=off']))"
        )
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr
        from PIL import Image

        frames = sorted((tmp_path / variant / "rgb").glob("*.png"))
        assert frames
        means[variant] = np.array([np.asarray(Image.open(p), np.float64).mean() for p in frames])
        for folder in ("labels", "depth"):
            for p in (run / folder).glob("*.png"):
                assert (tmp_path / variant / folder / p.name).read_bytes() == p.read_bytes()
    np.testing.assert_allclose(means["cuda"], means["llvm"], rtol=0.03)


def test_optix_brings_few_samples_closer_to_the_reference() -> None:
    """Mitsuba's OptiX denoiser (``denoiser = "optix"``, guided by albedo and sensor-frame
    normals): 4 denoised samples are nearer a 1,024-sample render of another seed than 4 raw
    ones, by a wide margin, and the mean brightness stays (the OIDN test's bar, on a corner of
    coloured walls, a checkered card and an area light: indirect light, where the noise is)."""
    from agrisim.config import RenderConfig
    from agrisim.plugins.render.mitsuba.options import MitsubaOptions
    from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer
    from agrisim.scene.camera import CameraModel
    from agrisim.scene.colour import linear_to_srgb
    from agrisim.scene.model import LabelTable, Light, Material, Mesh, Scene
    from agrisim.scene.transforms import look_at

    def quad(name: str, centre, half_u, half_v, material: Material) -> Mesh:  # noqa: ANN001
        c, a, b = (np.asarray(x, float) for x in (centre, half_u, half_v))
        v = np.array([c - a - b, c + a - b, c + a + b, c - a + b])
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
        return Mesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), [material], np.zeros(2, np.int32), uv)

    checker = np.full((64, 64, 4), 255, np.uint8)
    checker[..., :3] = np.where((np.indices((64, 64)).sum(0) // 8 % 2)[..., None] == 1, [220, 60, 60], [40, 40, 40])
    meshes = [
        quad("floor", (0, 0, 0), (1, 0, 0), (0, 1, 0), Material("floor", color=(0.8, 0.8, 0.8, 1.0))),
        quad("back", (0, 1, 1), (1, 0, 0), (0, 0, 1), Material("back", color=(0.2, 0.7, 0.3, 1.0))),
        quad("side", (-1, 0, 1), (0, 1, 0), (0, 0, 1), Material("side", color=(0.7, 0.3, 0.2, 1.0))),
        quad("card", (0.1, 0.2, 0.4), (0.3, 0, 0), (0, 0.1, 0.3), Material("card", albedo=checker)),
    ]
    lamp = Light("lamp", "area", np.array([0.6, -0.4, 1.8]), np.array([0.0, 0.0, -1.0]), intensity=3.0, radius=0.2)
    scene = Scene(meshes, [lamp], LabelTable())
    camera = CameraModel(96, 72, 70.0, 70.0, 47.5, 35.5)
    T = look_at(np.array([0.3, -1.6, 0.9]), np.array([0.0, 0.3, 0.5]))

    def radiance(**options: object) -> np.ndarray:
        settings = RenderConfig(hide_robots=True)
        return MitsubaRenderer(scene, None, settings, MitsubaOptions(variant="cuda", **options)).radiance(camera, T)

    def rmse(a: np.ndarray, b: np.ndarray) -> float:
        shown = lambda x: linear_to_srgb(np.clip(x, 0.0, 1.0))  # noqa: E731
        return float(np.sqrt(((shown(a) - shown(b)) ** 2).mean()))

    reference = radiance(spp=1024, seed=7, denoise="off")
    raw = radiance(spp=4, denoise="off")
    clean = radiance(spp=4, denoise="on", denoiser="optix")
    assert rmse(clean, reference) < 0.6 * rmse(raw, reference), (rmse(clean, reference), rmse(raw, reference))
    assert abs(clean.mean() / reference.mean() - 1.0) < 0.05
