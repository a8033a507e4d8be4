"""The kinds of backend and what a provider hook returns for one: :class:`BackendSpec`.

Kept apart from the registry so that the hook specifications can name these types without
importing the plugin manager.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

from pydantic import BaseModel

from agrisim.interfaces import (
    Bridge,
    DepthSensor,
    Exporter,
    Imager,
    PhysicsBackend,
    Planner,
    PlantReader,
    PlantSpecies,
    PoseSource,
    Reconstructor,
    Renderer,
    Rig,
    Room,
)
from agrisim.options import Options

Kind = Literal[
    "physics", "renderer", "sensor", "imager", "planner", "reconstructor", "plant", "sink", "bridge", "exporter"
]


@dataclass(frozen=True)
class KindInfo:
    """One kind of backend: how it is provided, configured and built."""

    hook: str
    """The provider hook returning its :class:`BackendSpec` list."""
    section: str | None
    """The configuration section choosing one (``[physics] backend = ...``); None: not chosen
    by a section's ``backend`` (an imager by ``[imager] model``, a pose source by ``recon.poses``, a plant file's format by the first reader that claims it, every plant is selectable by
    name, every sink is on, an exporter is named on the command line: ``agrisim export NAME``)."""
    abc: type | None
    """The ABC every factory result must be an instance of (None: any object, as a sink is a
    plugin object with event hooks)."""
    factory: str
    """The factory's signature, as the core calls it."""


#: The kinds of backend: the one table the registry, the episode, compare and the CLI read.
KINDS: dict[str, KindInfo] = {
    "physics": KindInfo("agrisim_physics", "physics", PhysicsBackend,
                        "factory(cell: Cell, options) -> PhysicsBackend"),
    "renderer": KindInfo("agrisim_renderers", "renderer", Renderer,
                         "factory(scene: Scene, cell: Cell, settings: RenderConfig, options) -> Renderer"),
    "sensor": KindInfo("agrisim_sensors", "sensor", DepthSensor,
                       "factory(scene: Scene, cell: Cell, settings: RenderConfig, options) -> DepthSensor"),
    "imager": KindInfo("agrisim_imagers", None, Imager,
                       "factory(settings: ImagerConfig, seed: int, options) -> Imager"),
    "planner": KindInfo("agrisim_planners", "planner", Planner,
                        "factory(options) -> Planner"),
    "reconstructor": KindInfo("agrisim_reconstructors", "recon", Reconstructor,
                              "factory(labels: LabelTable, options) -> Reconstructor"),
    "poses": KindInfo("agrisim_pose_sources", None, PoseSource,
                      "factory(options) -> PoseSource"),
    "plant": KindInfo("agrisim_plants", None, PlantSpecies,
                      "factory(options) -> PlantSpecies"),
    "format": KindInfo("agrisim_plant_formats", None, PlantReader,
                       "factory(options) -> PlantReader"),
    "room": KindInfo("agrisim_rooms", "room", Room,
                     "factory(cell: Cell, options) -> Room"),
    "rig": KindInfo("agrisim_rigs", "rig", Rig, "factory(settings: CellConfig, options) -> Rig"),
    "sink": KindInfo("agrisim_sinks", None, None,
                     "factory(run: Run, options) -> a plugin object with event hooks, or None"),
    "bridge": KindInfo("agrisim_bridges", None, Bridge,
                       "factory(session: LiveSession, options) -> Bridge"),
    "exporter": KindInfo("agrisim_exporters", None, Exporter,
                         "factory(options) -> Exporter"),
}  # fmt: skip

#: kind -> provider hook name
PROVIDER_HOOKS: dict[str, str] = {kind: info.hook for kind, info in KINDS.items()}

#: configuration section -> the kind it chooses
SECTIONS: dict[str, str] = {info.section: kind for kind, info in KINDS.items() if info.section}


class NoOptions(Options):
    """Options model for a backend that takes none."""


@dataclass(frozen=True)
class BackendSpec:
    """What a provider hook returns for one backend.

    ``factory(*context, options)`` builds the backend: the kind's context first, as
    :attr:`KindInfo.factory` names it (``factory(cell, options)`` for physics, ``factory(options)``
    for a planner), then ``options``, an instance of ``options_model`` validated from the user's
    configuration (its field docstrings are the documentation users see)."""

    name: str
    factory: Callable[..., Any]
    description: str
    options_model: type[BaseModel] = NoOptions
    limits: str = ""
    #: what the backend can do (:mod:`agrisim.capabilities`); None: the kind's defaults, which
    #: promise the least
    capabilities: Any = None
    #: ``preflight(config, options)``: checks that need the whole run configuration (a file the
    #: backend would overwrite), called while the run is validated, before anything is written;
    #: raises :class:`agrisim.errors.UserError`
    preflight: Callable[[Any, Any], None] | None = None
    #: filled in by the registry: the distribution that provided the spec
    distribution: str = field(default="", compare=False)


class LazyFactory:
    """A factory named by ``"module:attribute"`` and imported on its first call.

    Describing a backend (``agrisim plugins``, validating a configuration) then imports none of
    its libraries; building it does. A provider writes ``factory=lazy("pkg.backend:MyBackend")``."""

    def __init__(self, target: str) -> None:
        module, sep, attribute = target.partition(":")
        if not (module and sep and attribute):
            raise ValueError(f"lazy factory {target!r}: expected 'module:attribute'")
        self.target = target

    def resolve(self) -> Callable[..., Any]:
        """The factory itself (imports its module)."""
        module, _, attribute = self.target.partition(":")
        return getattr(importlib.import_module(module), attribute)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.resolve()(*args, **kwargs)

    def __repr__(self) -> str:
        return f"lazy({self.target!r})"


def lazy(target: str) -> LazyFactory:
    """A factory for ``"module:attribute"`` imported when the backend is first built."""
    return LazyFactory(target)
