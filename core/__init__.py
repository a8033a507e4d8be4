"""agrisim: robot arms photographing plants, with swappable backends.

The public API, all importable from here::

    from agrisim import build_config, Episode, run_episode      # run episodes from Python
    from agrisim import hookimpl, BackendSpec, Options          # write a plugin

``import agrisim`` stays light (a plugin importing ``hookimpl`` pulls in no robotics library);
the episode machinery loads on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from agrisim.options import Options
from agrisim.registry import BackendSpec, hookimpl, make_plugin_manager

if TYPE_CHECKING:
    from agrisim.config import RunConfig, build_config, load_toml
    from agrisim.episode import Episode, run_episode
    from agrisim.records import Run, RunSummary, SetpointResult

from agrisim.version import __version__  # noqa: E402 - re-exported

_LAZY = {
    "RunConfig": "agrisim.config",
    "build_config": "agrisim.config",
    "load_toml": "agrisim.config",
    "Episode": "agrisim.episode",
    "Run": "agrisim.records",
    "RunSummary": "agrisim.records",
    "SetpointResult": "agrisim.records",
    "run_episode": "agrisim.episode",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'agrisim' has no attribute {name!r}")


__all__ = [  # spelt out (not built from _LAZY) so that linters read it; a test keeps the two alike
    "BackendSpec",
    "Episode",
    "Options",
    "Run",
    "RunConfig",
    "RunSummary",
    "SetpointResult",
    "__version__",
    "build_config",
    "hookimpl",
    "load_toml",
    "make_plugin_manager",
    "run_episode",
]
