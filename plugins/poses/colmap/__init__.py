"""COLMAP as a pose source (``recon.poses = "colmap"``): the cameras ``agrisim colmap RUN``
estimated from the run's images alone and aligned to the world (:mod:`.photogrammetry`, on
pycolmap), read back for ``agrisim recon``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from agrisim import BackendSpec, hookimpl
from agrisim.interfaces import PoseSource


class ColmapPoses(PoseSource):
    """The poses of ``colmap/poses.json``, which ``agrisim colmap RUN`` writes."""

    def __init__(self, options: object) -> None:
        self.options = options

    def poses(self, run_dir: Path) -> dict[str, np.ndarray]:
        from agrisim.plugins.poses.colmap.photogrammetry import estimated_poses

        return estimated_poses(run_dir)


@hookimpl
def agrisim_pose_sources() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="colmap",
            factory=ColmapPoses,
            description="COLMAP's structure from motion on the run's images (agrisim colmap RUN first), aligned to "
            "the world by the true camera centres; the views it did not place are left out",
        )
    ]
