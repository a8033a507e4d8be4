"""The plugin manager and the backend registry.

Plugins are discovered only through the entry-point group ``agrisim``; the built-in backends are
declared in agrisim's own ``pyproject.toml`` exactly like a third-party package's. Environment:

* ``AGRISIM_DISABLE_PLUGIN_AUTOLOAD=1`` loads no entry points (tests register by hand).
* ``AGRISIM_LOAD_PLUGINS=a,b`` loads only the entry points with these names.
* ``AGRISIM_TRACE_PLUGINS=1`` prints every hook call to stderr.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from importlib import metadata
from typing import Any

import pluggy
from pydantic import BaseModel

from agrisim import hookspecs
from agrisim.capabilities import CAPABILITIES
from agrisim.errors import BackendFailure, PluginError, UserError
from agrisim.interfaces import PlanningFailed
from agrisim.kinds import KINDS, PROVIDER_HOOKS, BackendSpec, Kind, NoOptions

__all__ = [
    "DISTRIBUTION",
    "KINDS",
    "PROVIDER_HOOKS",
    "BackendSpec",
    "Kind",
    "NoOptions",
    "Registry",
    "blame",
    "hookimpl",
    "make_plugin_manager",
    "with_own_plugins",
]

hookimpl = pluggy.HookimplMarker(hookspecs.PROJECT)
#: the distribution whose entry points are agrisim's own plugins
DISTRIBUTION = "agrisim"


def make_plugin_manager(*, autoload: bool | None = None) -> pluggy.PluginManager:
    """A fresh plugin manager with agrisim's hookspecs and the installed plugins.

    Built per run (nothing happens at import time). ``check_pending()`` turns a misspelt hook
    implementation into an error instead of silently ignoring it."""
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    if autoload is None:
        autoload = os.environ.get("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "") in ("", "0")
    only = {n.strip() for n in os.environ.get("AGRISIM_LOAD_PLUGINS", "").split(",") if n.strip()}
    #: every installed plugin is loaded: a name that matches none of them is a mistake, not a
    #: plugin left out on purpose (read by :func:`loads_everything`)
    pm.agrisim_loads_everything = bool(autoload and not only)  # type: ignore[attr-defined]
    if autoload:
        seen: dict[str, str] = {}
        dists = _DistNames()
        for ep in metadata.entry_points(group=hookspecs.PROJECT):
            dist = dists.label(ep.dist)
            if ep.name in seen and seen[ep.name] != dist:
                # pluggy would silently keep whichever it met first
                raise PluginError(
                    f"entry point {ep.name!r} in group 'agrisim' is declared by both {seen[ep.name]} and {dist}"
                )
            seen[ep.name] = dist
            if only and ep.name not in only:
                pm.set_blocked(ep.name)
                continue
            try:  # import first so that a broken plugin is named in the error
                importlib.import_module(ep.module)
            except Exception as exc:
                raise PluginError(f"plugin {ep.name!r} from {dist} failed to import: {exc}") from exc
        unknown = only - set(seen)
        if unknown:
            raise PluginError(
                f"AGRISIM_LOAD_PLUGINS names unknown plugins {', '.join(sorted(unknown))}; installed: {', '.join(sorted(seen))}"
            )
        pm.load_setuptools_entrypoints(hookspecs.PROJECT)
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as exc:
        raise PluginError(f"plugin {exc.plugin!r} implements an unknown hook: {exc}") from exc
    if _tracing():
        pm.trace.root.setwriter(lambda msg: sys.stderr.write(msg))
        pm.enable_tracing()
    return pm


def with_own_plugins(pm: pluggy.PluginManager, names: Collection[str] | None = None) -> list[object]:
    """agrisim's own entry points' plugins (the distribution ``agrisim`` declares; ``names``:
    only those entry points), registered in ``pm`` where ``AGRISIM_LOAD_PLUGINS`` or
    ``AGRISIM_DISABLE_PLUGIN_AUTOLOAD`` left them out.

    The command line's built-in commands come from them, and every run's dataset sink, so the
    switches that choose a run's backends never take ``agrisim run`` or the run directory away:
    pytest loads its built-ins whatever ``PYTEST_DISABLE_PLUGIN_AUTOLOAD`` says, the same way."""
    own = []
    dists = _DistNames()
    for ep in metadata.entry_points(group=hookspecs.PROJECT):
        if ep.dist is None or dists.name(ep.dist) != DISTRIBUTION or (names is not None and ep.name not in names):
            continue
        plugin = pm.get_plugin(ep.name)
        if plugin is None:
            pm.unblock(ep.name)
            plugin = ep.load()
            pm.register(plugin, name=ep.name)
        own.append(plugin)
    return own


class _DistNames:
    """Distributions' names and versions, each read once: every read of ``Distribution.name``
    or ``.version`` parses its METADATA file again, and a distribution declares many entry points."""

    def __init__(self) -> None:
        #: by id, the distribution kept with its name and version (so that its id stays its own)
        self._seen: dict[int, tuple[metadata.Distribution, str, str]] = {}

    def _read(self, dist: metadata.Distribution) -> tuple[metadata.Distribution, str, str]:
        if id(dist) not in self._seen:
            self._seen[id(dist)] = (dist, dist.name, dist.version)
        return self._seen[id(dist)]

    def name(self, dist: metadata.Distribution) -> str:
        return self._read(dist)[1]

    def label(self, dist: metadata.Distribution | None) -> str:
        """``"name version"``, ``"?"`` without a distribution."""
        if dist is None:
            return "?"
        _, name, version = self._read(dist)
        return f"{name} {version}"


def loads_everything(pm: pluggy.PluginManager) -> bool:
    """Whether ``pm`` holds every installed plugin (not a selection by
    ``AGRISIM_LOAD_PLUGINS``, nor a hand-filled manager)."""
    return bool(getattr(pm, "agrisim_loads_everything", False))


def _tracing() -> bool:
    return os.environ.get("AGRISIM_TRACE_PLUGINS", "") not in ("", "0")


def _distribution_of(pm: pluggy.PluginManager, plugin: object) -> str:
    for plug, dist in pm.list_plugin_distinfo():
        if plug is plugin:
            return f"{dist.project_name} {dist.version}"
    return pm.get_name(plugin) or repr(plugin)


class Registry:
    """Backends of every kind, looked up by name."""

    def __init__(self, pm: pluggy.PluginManager) -> None:
        self.pm = pm
        self._specs: dict[str, dict[str, BackendSpec]] = {}

    def specs(self, kind: str) -> dict[str, BackendSpec]:
        """All backends of ``kind`` by name (collected once per registry)."""
        if kind not in PROVIDER_HOOKS:
            raise PluginError(f"unknown backend kind {kind!r}; kinds are {', '.join(PROVIDER_HOOKS)}")
        if kind not in self._specs:
            self._specs[kind] = self._collect(kind)
        return self._specs[kind]

    def _collect(self, kind: str) -> dict[str, BackendSpec]:
        hook_name = PROVIDER_HOOKS[kind]
        caller = getattr(self.pm.hook, hook_name)
        found: dict[str, BackendSpec] = {}
        for impl in caller.get_hookimpls():
            dist = _distribution_of(self.pm, impl.plugin)
            result = impl.function()  # one implementation at a time, to know whose spec is whose
            if _tracing():  # pluggy's tracer sees only calls through pm.hook
                names = [getattr(spec, "name", repr(spec)) for spec in result or []]
                sys.stderr.write(f"  {hook_name} [{dist}] -> {', '.join(names) or 'nothing'}\n")
            if not isinstance(result, (list, tuple)):
                raise PluginError(f"{hook_name}() of {dist} must return a list of BackendSpec")
            for spec in result:
                if not isinstance(spec, BackendSpec) or not spec.name or not callable(spec.factory):
                    raise PluginError(f"{hook_name}() of {dist} returned {spec!r}, not a BackendSpec")
                if not (isinstance(spec.options_model, type) and issubclass(spec.options_model, BaseModel)):
                    raise PluginError(f"{kind} {spec.name!r} of {dist}: options_model must be a pydantic model")
                if spec.name in found:
                    raise PluginError(
                        f"{kind} backend {spec.name!r} is provided twice: by {found[spec.name].distribution} and by {dist}"
                    )
                caps_type = CAPABILITIES.get(kind)
                caps = spec.capabilities
                if caps is None and caps_type is not None:
                    caps = caps_type()
                elif caps is not None and (caps_type is None or not isinstance(caps, caps_type)):
                    wanted = f"an agrisim.capabilities.{caps_type.__name__}" if caps_type else "None"
                    raise PluginError(f"{kind} {spec.name!r} of {dist}: capabilities must be {wanted}, got {caps!r}")
                found[spec.name] = BackendSpec(**{**spec.__dict__, "capabilities": caps, "distribution": dist})
        return dict(sorted(found.items()))

    def build(self, kind: str, spec: BackendSpec, *args: Any) -> Any:
        """Call ``spec``'s factory with the kind's arguments (:data:`agrisim.kinds.KINDS`) and
        check that it returned an instance of the kind's ABC.

        Raises:
            BackendFailure: the factory returned something else; names the plugin and its
                distribution. (Exceptions of the factory itself propagate unchanged.)"""
        built = spec.factory(*args)
        abc = KINDS[kind].abc
        if abc is not None and not isinstance(built, abc):
            origin = f" (from {spec.distribution})" if spec.distribution else ""
            raise BackendFailure(
                f"{kind} backend {spec.name!r}{origin}: its factory returned {type(built).__name__}, "
                f"not an {abc.__module__}.{abc.__qualname__}"
            )
        return built

    def get(self, kind: str, name: str) -> BackendSpec:
        """The backend ``name`` of ``kind``; an unknown name lists the available ones."""
        specs = self.specs(kind)
        if name not in specs:
            available = ", ".join(specs) or "none installed"
            raise PluginError(f"unknown {kind} backend {name!r}; available: {available}")
        return specs[name]


@contextmanager
def blame(kind: str, spec: BackendSpec, doing: str = "") -> Iterator[None]:
    """Re-raise an unexpected exception of a backend as :class:`BackendFailure` naming it."""
    try:
        yield
    except (UserError, PlanningFailed, BackendFailure):
        raise
    except Exception as exc:
        origin = f" (from {spec.distribution})" if spec.distribution else ""
        raise BackendFailure(
            f"{kind} backend {spec.name!r}{origin} failed{doing}: {type(exc).__name__}: {exc}"
        ) from exc
