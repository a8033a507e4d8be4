"""The readers of agrisim's plant file formats: what ``[plant_file]`` says, checked against what
the format can hold, then :func:`~agrisim.plugins.formats.plant_asset.load_plant` (meshes) or
:func:`~agrisim.plugins.formats.point_cloud.load_point_plant` (point clouds)."""

from __future__ import annotations

from pathlib import Path

from agrisim.config import PlantFileConfig
from agrisim.errors import UserError
from agrisim.interfaces import PlantReader
from agrisim.scene.model import Plant


def label_names(settings: PlantFileConfig) -> dict[int | str, str] | None:
    """``[plant_file] label_names`` with its ids as integers (TOML keys are strings)."""
    names = settings.label_names
    if names is None:
        return None
    return {int(k) if k.strip().isdigit() else k: v for k, v in names.items()}


class MeshFormat(PlantReader):
    """A mesh format :func:`~agrisim.plugins.formats.plant_asset.load_plant` reads."""

    def __init__(self, options: object = None) -> None:
        self.options = options

    def read(self, path: Path, settings: PlantFileConfig, *, place: bool = True) -> Plant:
        from agrisim.plugins.formats.plant_asset import load_plant

        names = label_names(settings)
        if names is not None and settings.label_texture is None:
            raise UserError(
                f"{path}: [plant_file] label_names names a label texture's ids or a point cloud's labels; "
                "give label_texture too"
            )
        return load_plant(
            path,
            label_texture=settings.label_texture,
            label_names=names,
            material_labels=settings.material_labels,
            alpha_cutoff=settings.alpha_cutoff,
            up=settings.up,
            scale=settings.scale,
            root=settings.root,
            place=place,
        )


class GltfFormat(MeshFormat):
    suffixes = (".glb", ".gltf")


class ObjFormat(MeshFormat):
    suffixes = (".obj",)


class PointFormat(PlantReader):
    """PLY and PCD point clouds (:func:`~agrisim.plugins.formats.point_cloud.load_point_plant`)."""

    suffixes = (".ply", ".pcd")
    holds = "point cloud"

    def __init__(self, options: object = None) -> None:
        self.options = options

    def read(self, path: Path, settings: PlantFileConfig, *, place: bool = True) -> Plant:
        from agrisim.plugins.formats.point_cloud import load_point_plant

        if (
            settings.label_texture is not None
            or settings.material_labels is not None
            or settings.alpha_cutoff is not None
        ):
            raise UserError(
                f"{path}: a point cloud has no textures or materials; [plant_file] label_names names its labels"
            )
        return load_point_plant(
            path,
            label_names=label_names(settings),
            up=settings.up,
            scale=settings.scale,
            root=settings.root,
            place=place,
        )
