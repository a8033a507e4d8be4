"""agrisim: robot arms photographing plants, with swappable backends.

The public API re-exported here is all a user or plugin author needs::

    from agrisim import RunConfig, build_config, run_episode, hookimpl, BackendSpec
"""

from __future__ import annotations

from agrisim.registry import BackendSpec, hookimpl, make_plugin_manager

__version__ = "0.1.0"

__all__ = ["BackendSpec", "hookimpl", "make_plugin_manager", "__version__"]
