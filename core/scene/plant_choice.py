"""The plant a run names (``--plant``): a registered species grown from the run's seed, a
glTF/GLB/OBJ file read with the ``[plant_file]`` settings, or a point cloud (PLY, PCD); then
drawn as points when ``[points]`` says so (``--as-points``, ``--point-size``)."""

from __future__ import annotations

from pathlib import Path

from agrisim.config import RunConfig, backend_options
from agrisim.errors import UserError
from agrisim.files.plant_asset import FORMATS, load_plant
from agrisim.files.point_cloud import POINT_FORMATS, load_point_plant
from agrisim.registry import Registry, blame
from agrisim.scene.model import Plant
from agrisim.scene.plant_cache import grown
from agrisim.scene.points import as_points, check_count, check_size


def draws_points(config: RunConfig) -> bool:
    """Is the run's plant drawn as points (a point-cloud file, or ``--as-points``)?"""
    return config.points.count is not None or Path(config.plant).suffix.lower() in POINT_FORMATS


def _check_points(config: RunConfig) -> None:
    if config.points.count is not None:
        check_count(config.points.count)
    if config.points.size is not None:
        check_size(config.points.size)


def check_plant_name(registry: Registry, config: RunConfig) -> None:
    """Is ``config.plant`` a registered species or an asset file that exists, and are the
    ``[points]`` settings sane? (Without growing or reading it.)"""
    _check_points(config)
    name = config.plant
    if name in registry.specs("plant"):
        return
    path = Path(name)
    if path.suffix.lower() in FORMATS + POINT_FORMATS:
        root = config.plant_file.root
        if (root / path if root is not None and not path.is_absolute() else path).is_file():
            return
        raise UserError(f"plant file {name} does not exist")
    resolve_plant(registry, config)  # raises the unknown-plant error with the species list


def _label_names(config: RunConfig) -> dict[int | str, str] | None:
    names = config.plant_file.label_names
    if names is None:
        return None
    return {int(k) if k.strip().isdigit() else k: v for k, v in names.items()}


def _read_file(config: RunConfig) -> Plant:
    name = config.plant
    table = config.plants.get(name) or {}
    if "age" in table:
        raise UserError(f"--plant-age: plant file {name} has no age; it applies to species that grow (helios:*)")
    if table:
        raise UserError(f"[plants.{name!r}]: a plant file takes no species options; [plant_file] reads it")
    f = config.plant_file
    if Path(name).suffix.lower() in POINT_FORMATS:
        if f.label_texture is not None or f.material_labels is not None or f.alpha_cutoff is not None:
            raise UserError(
                f"{name}: a point cloud has no textures or materials; [plant_file] label_names names its labels"
            )
        return load_point_plant(Path(name), label_names=_label_names(config), up=f.up, scale=f.scale, root=f.root)
    names = _label_names(config)
    if names is not None and f.label_texture is None:
        raise UserError(
            f"{name}: [plant_file] label_names names a label texture's ids or a point cloud's labels; give label_texture too"
        )
    return load_plant(
        Path(name),
        label_texture=f.label_texture,
        label_names=names,
        material_labels=f.material_labels,
        alpha_cutoff=f.alpha_cutoff,
        up=f.up,
        scale=f.scale,
        root=f.root,
    )


def plant_seed(name: str, value: object) -> int:
    """``[plants.NAME] seed`` (``--plant-seed``), checked: an integer 0 .. 2^32 - 1."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 2**32 - 1:
        raise UserError(f"[plants.{name}] seed (--plant-seed) must be an integer from 0 to {2**32 - 1}, got {value!r}")
    return value


def resolve_plant(registry: Registry, config: RunConfig) -> Plant:
    """The plant ``config.plant`` names: a registered species grown from its ``seed`` (its
    table's, else ``config.seed``), or a
    mesh or point-cloud file; drawn as points as ``config.points`` says."""
    _check_points(config)
    name = config.plant
    species = registry.specs("plant")
    if name in species:
        spec = species[name]
        table = dict(config.plants.get(name, {}))
        if "age" in table and "age" not in spec.options_model.model_fields:  # --plant-age's usual slip
            raise UserError(f"--plant-age: plant {name!r} has no age; it applies to species that grow (helios:*)")
        seed = plant_seed(name, table.pop("seed", config.seed))
        options = backend_options(spec.options_model, table, f"plant {name!r}")
        with blame("plant", spec, f" growing {name!r}"):
            plant: Plant = grown(name, options, seed, registry.build("plant", spec, options).build)
    elif Path(name).suffix.lower() in FORMATS + POINT_FORMATS or Path(name).exists():
        plant = _read_file(config)
    else:
        hint = registry.pm.hook.agrisim_plant_unavailable(name=name)  # e.g. a missing optional extra
        if hint:
            raise UserError(hint)
        available = ", ".join(species) or "none installed"
        raise UserError(
            f"unknown plant {name!r}; species: {available}; or a .glb/.gltf/.obj mesh or .ply/.pcd point cloud"
        )
    return as_points(plant, config.points.count, config.points.size, seed=config.seed)
