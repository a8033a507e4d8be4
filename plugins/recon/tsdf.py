"""The ``tsdf`` reconstructor: Open3D's TSDF fusion (``VoxelBlockGrid``) to a surface mesh,
per label.

Each label gets its own voxel block grid fed with the view's depth masked to that label (0
elsewhere, which Open3D skips), so a label's surface is fused only from pixels that carry it.
With several labels a further grid fuses every plant pixel (``all``); with one label ``all`` is
that label. (The legacy ``ScalableTSDFVolume`` of Open3D 0.20 integrates nothing on this build
of the wheel: the tensor API is the maintained one.)
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, model_validator

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import ReconstructorCapabilities
from agrisim.evaluation.views import View, as_pinhole, backproject
from agrisim.interfaces import ALL, Cloud, Reconstruction, Reconstructor, SurfaceMesh
from agrisim.scene.model import LabelTable

from .voxel_grid import VoxelGrid


class TsdfOptions(Options):
    """Options of the ``tsdf`` reconstructor."""

    voxel_size: float = Field(0.002, gt=0.0, le=0.1)
    """Edge of the TSDF voxels, m."""
    sdf_trunc: float = Field(0.008, gt=0.0, le=1.0)
    """Truncation distance of the signed distance, m (a few voxels)."""
    max_depth: float = Field(1.0, gt=0.0, le=100.0)
    """Pixels deeper than this are not fused, m (the paper drops depth > 1 m)."""
    min_weight: float = Field(1.0, ge=0.0, le=1000.0)
    """Surfaces are extracted where voxels were observed at least this often (weight)."""

    @model_validator(mode="after")
    def _trunc_covers_voxels(self) -> TsdfOptions:
        if self.sdf_trunc < self.voxel_size:
            raise ValueError(f"sdf_trunc ({self.sdf_trunc}) must be at least voxel_size ({self.voxel_size})")
        return self


class TsdfReconstructor(Reconstructor):
    """Fuses masked depth into one Open3D ``VoxelBlockGrid`` per label."""

    def __init__(self, labels: LabelTable, options: TsdfOptions | None = None) -> None:
        import open3d as o3d

        super().__init__(labels, options if options is not None else TsdfOptions())
        self._o3d = o3d
        self.names = {lab.id: lab.name for lab in labels.labels if lab.id != 0}
        if not self.names:
            raise ValueError("the label table has no plant label to reconstruct")
        grids = list(self.names.values()) + ([ALL] if len(self.names) > 1 else [])
        f32 = o3d.core.float32
        self.grids = {
            name: o3d.t.geometry.VoxelBlockGrid(
                attr_names=("tsdf", "weight", "color"),
                attr_dtypes=(f32, f32, f32),
                attr_channels=(1, 1, 3),
                voxel_size=self.options.voxel_size,
                block_resolution=8,
                block_count=4096,  # grows as needed
                device=o3d.core.Device("CPU:0"),
            )
            for name in grids
        }
        self._trunc = self.options.sdf_trunc / self.options.voxel_size

    def _masks(self, view: View) -> dict[str, np.ndarray]:
        labels = view.images.labels
        masks = {name: labels == i for i, name in self.names.items()}
        if ALL in self.grids:
            masks[ALL] = labels != 0
        return masks

    def integrate(self, view: View) -> dict[str, Cloud]:
        o3d = self._o3d
        o = self.options
        view = as_pinhole(view)  # (Open3D's fusion reads pinholes)
        K = o3d.core.Tensor(view.camera.K)
        extrinsic = o3d.core.Tensor(np.linalg.inv(view.world_T_camera))
        color = o3d.t.geometry.Image(np.ascontiguousarray(view.images.rgb))
        depth_mm = view.images.depth_mm()
        out = {}
        for name, mask in self._masks(view).items():
            if not mask.any():
                continue
            depth = o3d.t.geometry.Image(np.ascontiguousarray(np.where(mask, depth_mm, 0).astype(np.uint16)))
            grid = self.grids[name]
            blocks = grid.compute_unique_block_coordinates(
                depth, K, extrinsic, 1000.0, o.max_depth, trunc_voxel_multiplier=self._trunc
            )
            grid.integrate(
                blocks, depth, color, K, K, extrinsic, 1000.0, o.max_depth, trunc_voxel_multiplier=self._trunc
            )
            if name != ALL:
                points, colors = backproject(view, mask, o.max_depth)
                if len(points):
                    # what the view saw, at the fusion's resolution, for viewers
                    out[name] = VoxelGrid(o.voxel_size).add(points, colors)
        return out

    def _grid(self, name: str) -> object:
        return self.grids[name if name in self.grids else next(iter(self.names.values()))]

    def _mesh(self, name: str) -> SurfaceMesh:
        mesh = self._grid(name).extract_triangle_mesh(weight_threshold=self.options.min_weight)
        vertices = mesh.vertex.positions.numpy().astype(np.float64) if "positions" in mesh.vertex else np.zeros((0, 3))
        triangles = (
            mesh.triangle.indices.numpy().astype(np.int32) if "indices" in mesh.triangle else np.zeros((0, 3), np.int32)
        )
        colors = _colors(mesh.vertex.colors.numpy(), len(vertices)) if "colors" in mesh.vertex else None
        return SurfaceMesh(vertices, triangles, colors)

    def merged(self) -> dict[str, Cloud]:
        # the surface's vertices stand for the merged cloud while streaming
        clouds = {}
        for name in [*self.names.values(), ALL]:
            mesh = self._mesh(name)
            clouds[name] = Cloud(
                mesh.vertices, mesh.colors if mesh.colors is not None else _colors(None, len(mesh.vertices))
            )
        return clouds

    def result(self) -> Reconstruction:
        return Reconstruction(meshes={name: self._mesh(name) for name in [*self.names.values(), ALL]})


def _colors(values: np.ndarray | None, n: int) -> np.ndarray:
    c = np.asarray(values) if values is not None else np.zeros((0, 3))
    if len(c) != n:
        return np.full((n, 3), 200, np.uint8)
    return np.clip(np.rint(c * 255.0), 0, 255).astype(np.uint8)


@hookimpl
def agrisim_reconstructors() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="tsdf",
            factory=TsdfReconstructor,
            options_model=TsdfOptions,
            description="Open3D TSDF fusion (VoxelBlockGrid) of the labelled depth to a surface mesh, per label",
            # merged() streams clouds; the result is meshes. Views through a lens are resampled
            # onto their pinhole first (as_pinhole)
            capabilities=ReconstructorCapabilities(clouds=False, meshes=True, lenses=True),
        )
    ]
