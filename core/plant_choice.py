"""The plant a run names (``--plant``): a registered species grown from the run's seed, or a
file read with the ``[plant_file]`` settings by the first installed reader that claims it (a
glTF/GLB/OBJ mesh, a PLY/PCD point cloud, or a plugin's format); then drawn as points when
``[points]`` says so (``--as-points``, ``--point-size``)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from agrisim.bench import bench_layout, join_plants
from agrisim.config import RunConfig, backend_options
from agrisim.errors import UserError
from agrisim.interfaces import PlantReader
from agrisim.kinds import BackendSpec
from agrisim.registry import DISTRIBUTION, Registry, blame
from agrisim.scene.model import BenchPlant, Plant
from agrisim.scene.plant_cache import grown
from agrisim.scene.points import as_points, check_count, check_size


def plant_readers(registry: Registry) -> list[PlantReader]:
    """Every installed plant-file reader in the order they are asked: third parties' first (so
    that a plugin can take a suffix over), then agrisim's own, each group by name."""
    specs = list(registry.specs("format").values())
    own = [s for s in specs if s.distribution.startswith(f"{DISTRIBUTION} ")]
    readers = []
    for spec in [s for s in specs if s not in own] + own:
        with blame("format", spec, " opening"):
            readers.append(registry.build("format", spec, spec.options_model()))
    return readers


def reader_for(registry: Registry, path: Path) -> PlantReader | None:
    """The first installed reader that claims ``path``, or None."""
    return next((r for r in plant_readers(registry) if r.claims(path)), None)


def file_formats(registry: Registry) -> str:
    """The installed readers' suffixes as messages name them: ``a .glb/.gltf/.obj mesh or
    .ply/.pcd point cloud``."""
    held: dict[str, list[str]] = {}
    for reader in plant_readers(registry):
        held.setdefault(reader.holds, []).extend(reader.suffixes)
    return "a " + " or ".join(f"{'/'.join(suffixes)} {what}" for what, suffixes in held.items())


def draws_points(registry: Registry, config: RunConfig) -> bool:
    """Is the run's plant drawn as points (a point-cloud file, or ``--as-points``)?"""
    if config.points.count is not None:
        return True
    reader = None if config.plant in registry.specs("plant") else reader_for(registry, Path(config.plant))
    return reader is not None and reader.holds == "point cloud"


def _check_points(config: RunConfig) -> None:
    if config.points.count is not None:
        check_count(config.points.count)
    if config.points.size is not None:
        check_size(config.points.size)


def bench_configs(registry: Registry, config: RunConfig) -> list[tuple[BenchPlant, RunConfig]]:
    """Each plant of the run's bench with the run's settings for it alone (its plant, its seed)."""
    species = registry.specs("plant")
    out = []
    for slot in bench_layout(config):
        plants = dict(config.plants)
        if slot.plant in species:
            plants[slot.plant] = {**plants.get(slot.plant, {}), "seed": slot.seed}
        out.append((slot, config.model_copy(update={"plant": slot.plant, "plants": plants, "bench": None})))
    return out


def check_plant_name(registry: Registry, config: RunConfig) -> None:
    """Is ``config.plant`` (each of a bench's) a registered species or an asset file that exists,
    and are the ``[points]`` settings sane? (Without growing or reading it.)"""
    if config.bench is not None:
        if draws_points(registry, config):
            raise UserError("bench: plants are drawn as meshes; a point cloud or --as-points holds one plant")
        for slot, one in bench_configs(registry, config):
            with _on_bench(slot):
                check_plant_name(registry, one)
        return
    _check_points(config)
    name = config.plant
    if name in registry.specs("plant"):
        return
    path = Path(name)
    if reader_for(registry, path) is not None:
        root = config.plant_file.root
        if (root / path if root is not None and not path.is_absolute() else path).is_file():
            return
        raise UserError(f"plant file {name} does not exist")
    resolve_plant(registry, config)  # raises the unknown-plant error with the species list


def _read_file(registry: Registry, config: RunConfig, reader: PlantReader | None) -> Plant:
    name = config.plant
    table = config.plants.get(name) or {}
    if "age" in table:
        raise UserError(f"--plant-age: plant file {name} has no age; it applies to species that grow (helios:*)")
    if table:
        raise UserError(f"[plants.{name!r}]: a plant file takes no species options; [plant_file] reads it")
    if reader is None:  # a file of a format no reader claims
        raise UserError(f"{name}: not a plant file format agrisim reads (use {file_formats(registry)})")
    return reader.read(Path(name), config.plant_file)


@contextmanager
def _on_bench(slot: BenchPlant) -> Iterator[None]:
    """A bench plant's errors name it."""
    try:
        yield
    except UserError as exc:
        raise type(exc)(f"bench {slot.name}: {exc}") from None


def plant_seed(name: str, value: object) -> int:
    """``[plants.NAME] seed`` (``--plant-seed``), checked: an integer 0 .. 2^32 - 1."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 2**32 - 1:
        raise UserError(f"[plants.{name}] seed (--plant-seed) must be an integer from 0 to {2**32 - 1}, got {value!r}")
    return value


def species_options(spec: BackendSpec, name: str, table: Mapping[str, Any], default_seed: int) -> tuple[int, BaseModel]:
    """(seed, options) of species ``name`` from its ``[plants.NAME]`` table: ``seed`` (every
    species takes it; default: the run's) and the species' own options, validated."""
    table = dict(table)
    if "age" in table and "age" not in spec.options_model.model_fields:  # --plant-age's usual slip
        raise UserError(f"--plant-age: plant {name!r} has no age; it applies to species that grow (helios:*)")
    seed = plant_seed(name, table.pop("seed", default_seed))
    return seed, backend_options(spec.options_model, table, f"plant {name!r}")


def resolve_plant(registry: Registry, config: RunConfig) -> Plant:
    """The plant ``config.plant`` names: a registered species grown from its ``seed`` (its
    table's, else ``config.seed``), or a mesh or point-cloud file; drawn as points as
    ``config.points`` says. A bench's plants are joined into one (:func:`agrisim.bench.join_plants`)."""
    if config.bench is not None:
        plants = []
        for slot, one in (pairs := bench_configs(registry, config)):
            with _on_bench(slot):
                plants.append(resolve_plant(registry, one))
        return join_plants(plants, [slot for slot, _ in pairs])
    _check_points(config)
    name = config.plant
    species = registry.specs("plant")
    if name in species:
        spec = species[name]
        seed, options = species_options(spec, name, config.plants.get(name, {}), config.seed)
        with blame("plant", spec, f" growing {name!r}"):
            plant: Plant = grown(name, options, seed, registry.build("plant", spec, options).build)
    elif (reader := reader_for(registry, Path(name))) is not None or Path(name).exists():
        plant = _read_file(registry, config, reader)
    else:
        hint = registry.pm.hook.agrisim_plant_unavailable(name=name)  # e.g. a missing optional extra
        if hint:
            raise UserError(hint)
        available = ", ".join(species) or "none installed"
        raise UserError(f"unknown plant {name!r}; species: {available}; or {file_formats(registry)}")
    return as_points(plant, config.points.count, config.points.size, seed=config.seed)
