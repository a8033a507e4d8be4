"""The plant a run names (``--plant``): a registered species grown from the run's seed, or a
glTF/GLB/OBJ file read with the ``[plant_file]`` settings."""

from __future__ import annotations

from pathlib import Path

from agrisim.config import RunConfig, backend_options
from agrisim.errors import UserError
from agrisim.files.plant_asset import FORMATS, load_plant
from agrisim.registry import Registry, blame
from agrisim.scene.model import Plant


def check_plant_name(registry: Registry, config: RunConfig) -> None:
    """Is ``config.plant`` a registered species or an asset file that exists? (Without
    growing or reading it.)"""
    name = config.plant
    if name in registry.specs("plant"):
        return
    path = Path(name)
    if path.suffix.lower() in FORMATS:
        root = config.plant_file.root
        if (root / path if root is not None and not path.is_absolute() else path).is_file():
            return
        raise UserError(f"plant file {name} does not exist")
    resolve_plant(registry, config)  # raises the unknown-plant error with the species list


def resolve_plant(registry: Registry, config: RunConfig) -> Plant:
    """The plant ``config.plant`` names: a registered species grown from ``config.seed``, or a
    glTF/GLB/OBJ file."""
    name = config.plant
    species = registry.specs("plant")
    if name in species:
        spec = species[name]
        table = dict(config.plants.get(name, {}))
        if "age" in table and "age" not in spec.options_model.model_fields:  # --plant-age's usual slip
            raise UserError(f"--plant-age: plant {name!r} has no age; it applies to species that grow (helios:*)")
        options = backend_options(spec.options_model, table, f"plant {name!r}")
        with blame("plant", spec, f" growing {name!r}"):
            plant: Plant = registry.build("plant", spec, options).build(config.seed)
        return plant
    if Path(name).suffix.lower() in FORMATS or Path(name).exists():
        table = config.plants.get(name) or {}
        if "age" in table:
            raise UserError(f"--plant-age: plant file {name} has no age; it applies to species that grow (helios:*)")
        if table:
            raise UserError(f"[plants.{name!r}]: a plant file takes no species options; [plant_file] reads it")
        f = config.plant_file
        return load_plant(
            Path(name),
            label_texture=f.label_texture,
            material_labels=f.material_labels,
            alpha_cutoff=f.alpha_cutoff,
            up=f.up,
            scale=f.scale,
            root=f.root,
        )
    hint = registry.pm.hook.agrisim_plant_unavailable(name=name)  # e.g. a missing optional extra
    if hint:
        raise UserError(hint)
    available = ", ".join(species) or "none installed"
    raise UserError(f"unknown plant {name!r}; species: {available}; or a .glb/.gltf/.obj file")
