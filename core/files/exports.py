"""Exports of a run directory through the installed exporters (the ``exporter`` kind,
:class:`agrisim.interfaces.Exporter`): looked up by name, built with their options, run. The
exporters themselves are plugins (``agrisim.plugins.exporters`` and third-party ones); the core
names them only here, for the exports a run writes itself."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from agrisim.errors import PluginError
from agrisim.interfaces import Exporter
from agrisim.kinds import BackendSpec
from agrisim.registry import Registry, blame

#: the exports every run that rendered frames writes itself, once ``run.json`` says how it ended
#: (when the exporter is installed): nerfstudio's ``transforms.json`` and masks
RUN_EXPORTS: tuple[str, ...] = ("nerfstudio",)


def build_exporter(
    registry: Registry, name: str, options: Mapping[str, Any] | None = None
) -> tuple[BackendSpec, Exporter]:
    """The exporter ``name`` (an unknown one lists those installed) built with ``options``,
    validated by its spec's options model."""
    from agrisim.config import backend_options

    spec = registry.get("exporter", name)
    validated = backend_options(spec.options_model, options or {}, f"exporter {name!r}")
    exporter: Exporter = registry.build("exporter", spec, validated)
    return spec, exporter


def run_export(
    spec: BackendSpec,
    exporter: Exporter,
    run_dir: Path,
    out: Path | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """``exporter``'s export of ``run_dir`` into ``out`` (default: ``run_dir /
    exporter.default_out``); returns what it wrote. Its bad-input refusals
    (:class:`agrisim.errors.UserError`) pass unchanged, any other failure becomes a
    :class:`agrisim.errors.BackendFailure` naming it."""
    run_dir = Path(run_dir)
    if out is None:
        default = Path(exporter.default_out)
        if default.is_absolute() or ".." in default.parts:
            raise PluginError(
                f"exporter {spec.name!r} (from {spec.distribution}): its default_out {exporter.default_out!r} is not inside the run"
            )
        out = run_dir / default
    with blame("exporter", spec, f" exporting {run_dir}"):
        written = exporter.export(run_dir, Path(out), overwrite, progress)
    return Path(written)
