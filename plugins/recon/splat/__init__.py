"""The ``splat`` reconstructor: 3D Gaussian splatting (gsplat, PyTorch, one CUDA GPU) trained
on a run's views with their true poses, measured as the paper measured its NeRFs (PSNR and SSIM
of held-out views) and, beyond it, against the true geometry.

What each part does:

* :mod:`.split` holds out a seeded share of the views; :mod:`.cameras` hands OpenCV's K and pose
  to gsplat (whose pixel centres sit at +0.5); :mod:`.quality` computes PSNR and SSIM;
  :mod:`.ply` writes the splats in the PLY layout 3D Gaussian splatting viewers open. None of
  these needs PyTorch (CI tests them).
* :mod:`.train` fits the Gaussians (gsplat's rasteriser and its default densification
  strategy) and renders colour and depth; :mod:`.reconstructor` collects the views, trains,
  evaluates and returns the outputs (``RUN/splat/``, the metrics, the plant's splat centres as
  its clouds); :mod:`.recording` writes the training as a Rerun recording where Rerun is
  installed. Views through a lens are resampled onto the pinhole of their K first
  (:func:`agrisim.evaluation.views.as_pinhole`): gsplat trains and is scored on undistorted views.
"""

from __future__ import annotations

import importlib.util
from typing import Any

from agrisim import BackendSpec, hookimpl
from agrisim.capabilities import ReconstructorCapabilities
from agrisim.errors import ConfigError
from agrisim.kinds import lazy

from .options import SplatOptions

#: the folder of the run directory the reconstructor writes
FOLDER = "splat"


def preflight(config: Any, options: SplatOptions) -> None:
    """Refuse before anything runs when gsplat is not installed (the core checks the GPU and
    the hidden arms, which the capabilities declare)."""
    if importlib.util.find_spec("gsplat") is None:
        raise ConfigError(
            "reconstructor 'splat' needs gsplat: pip install 'agrisim[splat]' (PyTorch with CUDA, gsplat)"
        )


@hookimpl
def agrisim_reconstructors() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="splat",
            factory=lazy("agrisim.plugins.recon.splat.reconstructor:SplatReconstructor"),
            options_model=SplatOptions,
            description="3D Gaussian splatting (gsplat) on the views with true poses; held-out PSNR/SSIM, depth and splat-centre accuracy",
            capabilities=ReconstructorCapabilities(
                clouds=True, needs_cuda=True, needs_hidden_robots=True, folder=FOLDER, lenses=True
            ),
            preflight=preflight,
        )
    ]
