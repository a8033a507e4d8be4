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

from agrisim.options import Options

Kind = Literal["physics", "renderer", "planner", "reconstructor", "plant", "sink"]

#: kind -> provider hook name
PROVIDER_HOOKS: dict[str, str] = {
    "physics": "agrisim_physics",
    "renderer": "agrisim_renderers",
    "planner": "agrisim_planners",
    "reconstructor": "agrisim_reconstructors",
    "plant": "agrisim_plants",
    "sink": "agrisim_sinks",
}


class NoOptions(Options):
    """Options model for a backend that takes none."""


@dataclass(frozen=True)
class BackendSpec:
    """What a provider hook returns for one backend.

    ``factory(options, **context)`` builds the backend; ``options`` is an instance of
    ``options_model`` validated from the user's configuration (its field docstrings are the
    documentation users see).
    """

    name: str
    factory: Callable[..., Any]
    description: str
    options_model: type[BaseModel] = NoOptions
    limits: str = ""
    #: what the backend can do (:mod:`agrisim.capabilities`); None: the kind's defaults, which
    #: promise the least
    capabilities: Any = None
    #: filled in by the registry: the distribution that provided the spec
    distribution: str = field(default="", compare=False)


class LazyFactory:
    """A factory named by ``"module:attribute"`` and imported on its first call.

    Describing a backend (``agrisim plugins``, validating a configuration) then imports none of
    its libraries; building it does. A provider writes ``factory=lazy("pkg.backend:MyBackend")``.
    """

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
