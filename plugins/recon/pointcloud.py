"""The ``pointcloud`` reconstructor: the paper's method (section 4.2), one cloud per label.

Per view: drop depth beyond ``max_depth`` (1 m), keep the pixels of the label, back-project
with the pinhole of Eq. 1, move to the world by the camera's pose. The views are merged on a
1 mm voxel grid, as the paper's ``voxel_down_sample``, but incrementally: the grid keeps per-voxel
sums, so the merge after any number of views equals one downsample of all points together.
"""

from __future__ import annotations

from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import ReconstructorCapabilities
from agrisim.evaluation.views import View, backproject
from agrisim.interfaces import ALL, Cloud, Reconstruction, Reconstructor
from agrisim.scene.model import LabelTable

from .voxel_grid import VoxelGrid


class PointCloudOptions(Options):
    """Options of the ``pointcloud`` reconstructor."""

    voxel_size: float = Field(0.001, gt=0.0, le=0.1)
    """Edge of the voxels points are averaged in, m (the paper: 1 mm)."""
    max_depth: float = Field(1.0, gt=0.0, le=100.0)
    """Pixels deeper than this are dropped, m (the paper: 1 m)."""


class PointCloudReconstructor(Reconstructor):
    """Back-projects every labelled pixel and merges the views per label on a voxel grid."""

    def __init__(self, labels: LabelTable, options: PointCloudOptions | None = None) -> None:
        super().__init__(labels, options if options is not None else PointCloudOptions())
        self.names = {lab.id: lab.name for lab in labels.labels if lab.id != 0}
        self.grids = {name: VoxelGrid(self.options.voxel_size) for name in self.names.values()}

    def integrate(self, view: View) -> dict[str, Cloud]:
        out = {}
        for label_id, name in self.names.items():
            mask = view.images.labels == label_id
            if not mask.any():
                continue
            points, colors = backproject(view, mask, self.options.max_depth)
            if len(points):
                out[name] = self.grids[name].add(points, colors)
        return out

    def merged(self) -> dict[str, Cloud]:
        clouds = {name: grid.cloud() for name, grid in self.grids.items()}
        clouds[ALL] = VoxelGrid.union(list(self.grids.values())).cloud()
        return clouds

    def result(self) -> Reconstruction:
        return Reconstruction(clouds=self.merged())


@hookimpl
def agrisim_reconstructors() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="pointcloud",
            factory=PointCloudReconstructor,
            options_model=PointCloudOptions,
            description="the paper's method: back-projected labelled pixels merged on a 1 mm voxel grid, per label",
            capabilities=ReconstructorCapabilities(clouds=True, meshes=False, lenses=True),
        )
    ]
