"""The ``helios`` plant library: crop models grown by PyHelios (``pip install agrisim[helios]``).

Every model of the installed Helios plant-architecture library is a species ``helios:<model>``
(``helios:tomato``, ``helios:bean``, ``helios:strawberry`` ...). ``build(seed)`` seeds Helios's
random generator, grows one plant of the model to its age in days (``--plant-age``, or the
model's default from :data:`DEFAULT_AGES`) and converts it with :mod:`.convert`: textured
triangles, organ labels (leaf, stem, petiole, peduncle, flower, fruit) and one leaf instance per
Helios leaf object. The same seed and age give identical arrays.

Plants are grown at their real size. The routine's cameras move on a 0.5 m hemisphere, so a plant
larger than the procedural species' cylinder (:data:`agrisim.scene.model.PLANT_FIT_RADIUS` from the stem,
:data:`agrisim.scene.model.PLANT_FIT_HEIGHT` above the soil) is scaled down uniformly, with a note in
``Plant.notes``, or refused with ``fit = "refuse"``. The default ages keep most crops at or near
their real size; trees and maize are young plants that still need shrinking.

PyHelios is imported only when a plant is listed or grown, so this module imports without it;
``agrisim_plant_unavailable`` then explains that ``helios:*`` plants need the extra.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.errors import UserError
from agrisim.interfaces import PlantSpecies
from agrisim.scene.model import PLANT_FIT_HEIGHT, PLANT_FIT_RADIUS, Mesh, Plant

from . import convert as hc

PREFIX = "helios:"
EXTRA_HINT = "pip install 'agrisim[helios]'"
MAX_AGE = 3650.0
"""Oldest plant the options accept, days (ten years: the library's trees)."""

DEFAULT_AGE = 30.0
"""Age of a model missing from :data:`DEFAULT_AGES`, days."""

#: Default age per model, days: old enough to show the crop's habit (and for strawberry and rice
#: its flowers and fruit), young enough to fit the routine's cylinder at or near real size where
#: the crop allows it. Measured with PyHelios 0.1.38 (scale at seed 0 in brackets when < 1).
DEFAULT_AGES: dict[str, float] = {
    "asparagus": 25,
    "bean": 20,
    "bindweed": 12,
    "bougainvillea": 25,
    "butterlettuce": 40,
    "capsicum": 40,
    "cheeseweed": 30,
    "cherrytomato": 15,  # (0.81)
    "cowpea": 25,
    "groundcherryweed": 25,
    "maize": 10,  # (0.64) a seedling: maize is 0.57 m tall after ten days
    "puncturevine": 15,
    "rice": 60,  # grain heads at 60 days
    "sorghum": 15,
    "soybean": 20,
    "strawberry": 60,  # (0.67) flowers and fruit
    "sugarbeet": 40,  # (0.79)
    "tomato": 20,  # (0.81)
    "wheat": 15,  # (0.81) the spike has emerged
    # trees and vines stay leafless (dormant) for months; all need strong shrinking
    "almond": 120,
    "almond_aldrich": 180,
    "almond_independence": 180,
    "almond_wood_colony": 180,
    "apple": 180,
    "apple_fruitingwall": 30,
    "easternredbud": 15,
    "grapevine_VSP": 30,
    "grapevine_Wye": 30,
    "olive": 180,
    "pistachio": 180,
    "walnut": 180,
}


class HeliosPlantOptions(Options):
    """Options of a Helios plant."""

    age: float | None = Field(None, gt=0.0, le=MAX_AGE, allow_inf_nan=False)
    """Age of the plant in days (``--plant-age``); None: the model's default, chosen so that
    the plant fits the cameras' hemisphere at or near its real size."""
    fit: Literal["scale", "refuse"] = "scale"
    """A plant larger than the routine's cylinder (0.27 m from the stem, 0.39 m above the soil):
    ``scale`` shrinks it uniformly about its base (noted in the plant), ``refuse`` stops with an
    error naming its size."""


# ------------------------------------------------------------------------------- PyHelios


def helios_available() -> bool:
    """Is PyHelios installed (without importing it)?"""
    try:
        return importlib.util.find_spec("pyhelios") is not None
    except (ImportError, ValueError):  # e.g. sys.modules["pyhelios"] = None blocks it
        return False


@dataclass(frozen=True)
class _PyHelios:
    """The parts of PyHelios the plugin uses."""

    Context: Any
    PlantArchitecture: Any
    vec3: Any
    version: str


@functools.cache
def _pyhelios() -> _PyHelios:
    """PyHelios, imported on first use; a UserError naming the extra when it is missing."""
    if not helios_available():
        raise UserError(f"Helios plants need PyHelios, an optional extra: {EXTRA_HINT}")
    try:
        import pyhelios
        from pyhelios.types import vec3
    except Exception as exc:  # e.g. its native library fails to load
        raise UserError(f"PyHelios is installed but cannot be loaded ({exc}); reinstall it: {EXTRA_HINT}") from exc
    if pyhelios.PlantArchitecture is None:  # a PyHelios built without the plugin
        raise UserError(f"PyHelios {pyhelios.__version__} lacks its plant-architecture plugin: {EXTRA_HINT}")
    return _PyHelios(pyhelios.Context, pyhelios.PlantArchitecture, vec3, str(pyhelios.__version__))


@functools.cache
def available_models() -> tuple[str, ...]:
    """The plant models of the installed Helios library (empty without a working PyHelios:
    :func:`agrisim_plant_unavailable` then says why)."""
    if not helios_available():
        return ()
    try:
        ph = _pyhelios()
    except UserError:
        return ()
    with ph.Context() as ctx, ph.PlantArchitecture(ctx) as pa:
        return tuple(pa.getAvailablePlantModels())


def default_age(model: str) -> float:
    """The model's default age in days."""
    return float(DEFAULT_AGES.get(model, DEFAULT_AGE))


# ------------------------------------------------------------------------------- growing


@contextmanager
def helios_plant(model: str, age: float, seed: int) -> Iterator[tuple[Any, Any, int]]:
    """``(context, plant_architecture, plant_id)``: one plant of Helios's ``model`` grown to
    ``age`` days from ``seed`` at the origin, alive inside the ``with`` block."""
    ph = _pyhelios()
    with ph.Context() as ctx:
        # Helios's plant architecture draws from the context's generator only: seeding it makes
        # the plant a function of (model, age, seed).
        ctx.seedRandomGenerator(int(seed) & 0xFFFFFFFF)
        with ph.PlantArchitecture(ctx) as pa:
            pa.disableMessages()  # progress bars on stdout
            pa.loadPlantModelFromLibrary(model)
            plant_id = pa.buildPlantInstanceFromLibrary(ph.vec3(0.0, 0.0, 0.0), float(age))
            yield ctx, pa, plant_id


def grow(model: str, seed: int, options: HeliosPlantOptions | None = None) -> Plant:
    """Grow Helios's ``model`` from ``seed`` (deterministic) as an agrisim plant."""
    opts = options or HeliosPlantOptions()
    ph = _pyhelios()
    if model not in available_models():
        raise UserError(f"unknown Helios model {model!r}; models: {', '.join(available_models())}")
    age = float(opts.age) if opts.age is not None else default_age(model)
    name = f"{PREFIX}{model}"
    with helios_plant(model, age, seed) as (ctx, pa, plant_id):
        prims = hc.fetch(ctx, ctx.getAllUUIDs())
        if len(prims) == 0:
            raise UserError(f"{name} at {age:g} days has no geometry yet; give an older --plant-age")
        labels, instances = hc.organ_labels(pa, ctx, plant_id, prims)
        mesh = hc.to_mesh(ctx, prims, labels, instances, name)
    notes = [f"grown by PyHelios {ph.version}: {model} at {age:g} days, seed {seed}"]
    mesh, note = _fit(mesh, name, age, opts.fit)
    if note:
        notes.append(note)
    return Plant(name=name, mesh=mesh, labels=hc.label_table(labels), organs=True, seed=int(seed), notes=notes)


def _fit(mesh: Mesh, name: str, age: float, fit: str) -> tuple[Mesh, str]:
    """The mesh shrunk into the routine's cylinder (or a UserError with ``fit="refuse"``), and a
    note saying by how much ("" when it fits)."""
    v = mesh.vertices
    radius = float(np.hypot(v[:, 0], v[:, 1]).max())
    height = float(v[:, 2].max())
    scale = min(1.0, PLANT_FIT_RADIUS / max(radius, 1e-9), PLANT_FIT_HEIGHT / max(height, 1e-9))
    if scale >= 1.0:
        return mesh, ""
    size = f"{name} at {age:g} days reaches {radius:.2f} m from its stem and {height:.2f} m high"
    limit = f"the routine's cameras allow {PLANT_FIT_RADIUS:.2f} m and {PLANT_FIT_HEIGHT:.2f} m"
    if fit == "refuse":
        raise UserError(f'{size}; {limit}: give a younger --plant-age or set plants."{name}".fit = "scale"')
    scaled = dataclasses.replace(mesh, vertices=v * scale)
    return scaled, f"{size}; scaled by {scale:.3f} to fit ({limit})"


class HeliosSpecies(PlantSpecies):
    """One Helios model; ``build(seed)`` grows a plant."""

    model: str = ""

    def __init__(self, options: HeliosPlantOptions | None = None, **_context: object) -> None:
        super().__init__(options if options is not None else HeliosPlantOptions())

    def build(self, seed: int) -> Plant:
        return grow(self.model, seed, self.options)


@functools.cache
def species_class(model: str) -> type[HeliosSpecies]:
    """The :class:`HeliosSpecies` subclass of ``model`` (one per model, ``factory(options)``)."""
    cls = type(f"Helios_{model}", (HeliosSpecies,), {"model": model, "__doc__": f"Helios's {model} model."})
    cls.__module__ = __name__
    return cls


# ------------------------------------------------------------------------------- hooks


@hookimpl
def agrisim_plants() -> list[BackendSpec]:
    """Every model of the installed Helios library (none without PyHelios)."""
    models = available_models()
    if not models:
        return []
    version = _pyhelios().version
    return [
        BackendSpec(
            name=f"{PREFIX}{model}",
            factory=species_class(model),
            description=f"{model} grown by PyHelios {version} (default age {default_age(model):g} days)",
            options_model=HeliosPlantOptions,
            limits='shrunk to fit the routine\'s 0.27 x 0.39 m cylinder when larger (fit = "refuse" refuses instead)',
        )
        for model in models
    ]


@hookimpl
def agrisim_plant_unavailable(name: str) -> str | None:
    """Why ``helios:<model>`` cannot be grown: PyHelios missing, or no such model."""
    if not name.startswith(PREFIX):
        return None
    if not helios_available():
        return f"plant {name!r} needs PyHelios, an optional extra: {EXTRA_HINT}"
    try:
        _pyhelios()
    except UserError as exc:
        return f"plant {name!r}: {exc}"
    models = available_models()
    if name[len(PREFIX) :] not in models:
        return f"unknown Helios model {name[len(PREFIX) :]!r}; models: {', '.join(models)}"
    return None
