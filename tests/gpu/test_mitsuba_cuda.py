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
