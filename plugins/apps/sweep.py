"""Planning a sweep (``agrisim sweep SPEC``): a grid of runs from one TOML file, every cell's
configuration built and validated, and the output folder checked, before Ray starts or
anything is written (:func:`plan_sweep`). Running the plan is :mod:`agrisim.plugins.apps.sweep_run`.

A spec is a ``--config`` file with two tables of its own::

    plant = "bog_marshcress"             # the rest: the base configuration of every run
    [axes]                               # dotted setting names, as --set takes them
    pcg_seed = [1, 2, 3]
    "renderer.backend" = ["raycast", "mitsuba"]
    [sweep]                              # optional
    after = ["coco", "nerfstudio"]       # follow-ups on each complete run (colmap, coco, nerfstudio)
    gpu = "auto"                         # auto (by renderer), true (every run takes a GPU), false
    [sweep.colmap]                       # options of the colmap follow-up (agrisim colmap's flags)
    matcher = "exhaustive"

The grid is the product of the axes, in the order the spec lists them; each cell is a
complete run directory ``OUT/<name>``, its name made of its axis values
(``pcg_seed=1,backend=raycast``).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agrisim.config import RunConfig, backend_options, build_config, load_toml
from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.plugins.apps.compare_plan import check_same_settings, run_dir_state
from agrisim.plugins.apps.flags import apply_sets, set_dotted
from agrisim.validation import check_run

#: the follow-ups a spec's ``[sweep] after`` may name: what ``agrisim colmap``, ``agrisim export
#: coco`` and ``agrisim export nerfstudio`` do (the last two through their installed exporters),
#: on each complete run
FOLLOW_UPS: tuple[str, ...] = ("colmap", "coco", "nerfstudio")
#: the keyword arguments of the colmap follow-up (``[sweep.colmap]``): ``agrisim colmap``'s flags
COLMAP_OPTIONS: tuple[str, ...] = (
    "matcher",
    "intrinsics",
    "priors",
    "prior_std_mm",
    "overlap",
    "max_features",
    "peak_threshold",
    "attempts",
    "seed",
)
#: the manifest of a sweep, in ``OUT``
MANIFEST = "sweep.json"
#: settings a sweep sets for each run itself (where it goes), never the spec's
OWN_OUTPUT = ("out", "overwrite", "resume")


@dataclass(frozen=True)
class SweepSpec:
    """A spec file read: the base configuration, the axes and the ``[sweep]`` options."""

    path: Path
    base: dict[str, Any]
    axes: dict[str, list[Any]]
    after: tuple[str, ...] = ()
    gpu: bool | None = None
    """True: every run takes a GPU; False: none does; None (``auto``): by the renderer."""
    colmap: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Cell:
    """One run of the grid: its axis values, its run directory and validated configuration.

    ``device`` is ``gpu`` (its renderer asks for CUDA), ``auto`` (a GPU where the cluster has
    one: a Dr.Jit renderer with ``variant = "auto"``) or ``cpu``. ``action`` says what the
    sweep does: ``run`` (a new run), ``resume`` (an unfinished run in its folder), ``after``
    (complete, follow-ups missing) or ``skip`` (complete with every follow-up, ``--resume``).
    """

    name: str
    settings: dict[str, Any]
    run_dir: Path
    config: dict[str, Any]  # the RunConfig as JSON, what the Ray task receives
    device: str = "cpu"
    views: int = 0
    """Views the run takes if every setpoint is reached (for the progress bar)."""
    action: str = "run"


@dataclass(frozen=True)
class SweepPlan:
    """Everything a sweep will do, validated; building it writes nothing."""

    spec: SweepSpec
    out: Path
    cells: tuple[Cell, ...]
    overwrite: bool = False
    resume: bool = False

    def to_json(self) -> dict[str, Any]:
        """The plan as ``sweep.json`` records it."""
        return {
            "spec": str(self.spec.path),
            "out": str(self.out),
            "axes": self.spec.axes,
            "base": self.spec.base,
            "after": list(self.spec.after),
            "gpu": "auto" if self.spec.gpu is None else self.spec.gpu,
            "colmap": self.spec.colmap,
        }


# ---------------------------------------------------------------------------------- the spec


def read_spec(path: Path, sets: Sequence[str] = ()) -> SweepSpec:
    """Read a spec file: ``[axes]`` and ``[sweep]`` apart, the rest the base configuration
    (``sets``: ``--set KEY=VALUE`` items on top of it). Malformed tables are a UserError."""
    doc = load_toml(Path(path))
    axes_table = doc.pop("axes", None)
    sweep = doc.pop("sweep", {})
    base = dict(doc)
    apply_sets(base, sets)
    if axes_table is None or not isinstance(axes_table, dict) or not axes_table:
        raise UserError(f"{path}: the grid is empty: give [axes] with at least one setting and its values")
    axes = _flatten_axes(axes_table)
    for key, values in axes.items():
        if not isinstance(values, list):
            raise UserError(f"{path}: axis {key!r} must be a list of values, got {values!r}")
        if not values:
            raise UserError(f"{path}: the grid is empty: axis {key!r} has no values")
        if key.split(".")[0] == "output" and key.split(".")[-1] in OWN_OUTPUT:
            raise UserError(f"{path}: axis {key!r}: the sweep puts every run in --out DIR itself")
        seen = [json.dumps(v, sort_keys=True, default=str) for v in values]
        if len(set(seen)) < len(seen):
            raise UserError(f"{path}: axis {key!r} lists a value more than once")
    if not isinstance(sweep, dict):
        raise UserError(f"{path}: [sweep] must be a table")
    unknown = sorted(set(sweep) - {"after", "gpu", "colmap"})
    if unknown:
        raise UserError(f"{path}: [sweep] {unknown[0]!r} is unknown; allowed: after, gpu, colmap")
    after = sweep.get("after", [])
    if not isinstance(after, list) or not all(isinstance(a, str) for a in after):
        raise UserError(f"{path}: [sweep] after must be a list of names ({', '.join(FOLLOW_UPS)})")
    bad = [a for a in after if a not in FOLLOW_UPS]
    if bad:
        raise UserError(f"{path}: [sweep] after: unknown {bad[0]!r}; allowed: {', '.join(FOLLOW_UPS)}")
    gpu = sweep.get("gpu", "auto")
    if gpu not in ("auto", True, False):
        raise UserError(f'{path}: [sweep] gpu must be "auto", true or false, got {gpu!r}')
    colmap = sweep.get("colmap", {})
    if not isinstance(colmap, dict):
        raise UserError(f"{path}: [sweep.colmap] must be a table")
    bad = sorted(set(colmap) - set(COLMAP_OPTIONS))
    if bad:
        raise UserError(f"{path}: [sweep.colmap] {bad[0]!r} is unknown; allowed: {', '.join(COLMAP_OPTIONS)}")
    if colmap and "colmap" not in after:
        raise UserError(f"{path}: [sweep.colmap] is given but [sweep] after does not name colmap")
    return SweepSpec(
        path=Path(path),
        base=base,
        axes=axes,
        after=tuple(dict.fromkeys(after)),
        gpu=None if gpu == "auto" else bool(gpu),
        colmap=dict(colmap),
    )


def _flatten_axes(table: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``[axes]`` as dotted key -> values: TOML reads ``renderer.backend = [...]`` as nested
    tables, ``"renderer.backend" = [...]`` as one key; both mean the same setting."""
    out: dict[str, Any] = {}
    for key, value in table.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten_axes(value, f"{dotted}."))
        else:
            out[dotted] = value
    return out


# ---------------------------------------------------------------------------------- the cells


def _slug(value: Any) -> str:
    """A value as a folder name shows it: paths by their file name, the rest as JSON, every
    character a shell or a file system might trip on replaced."""
    if isinstance(value, str):
        text = Path(value).name if ("/" in value or "\\" in value) else value
    elif isinstance(value, bool):
        text = str(value).lower()
    elif isinstance(value, (int, float)):
        text = f"{value:g}" if isinstance(value, float) else str(value)
    else:
        text = json.dumps(value, sort_keys=True, separators=(",", ":"))
    return re.sub(r"[^A-Za-z0-9._+-]+", "_", text).strip("_") or "_"


def cell_names(axes: Sequence[str], cells: Sequence[Sequence[Any]]) -> list[str]:
    """A readable, stable folder name per cell: ``key=value`` per axis, joined by commas.

    ``key`` is the axis's last part (``ambient`` of ``renderer.raycast.ambient``) unless two axes
    share it, then the whole dotted name. Names that would still collide (two plant files named
    alike in other folders) get a short hash of their values.
    """
    short = [a.rsplit(".", 1)[-1] for a in axes]
    keys = [s if short.count(s) == 1 else a for s, a in zip(short, axes, strict=True)]
    names = [",".join(f"{k}={_slug(v)}" for k, v in zip(keys, values, strict=True)) for values in cells]
    for i, name in enumerate(names):
        if names.count(name) > 1:
            digest = hashlib.blake2b(json.dumps(list(cells[i]), default=str).encode(), digest_size=4).hexdigest()
            names[i] = f"{name},{digest}"
    return names


def _views(config: RunConfig) -> int:
    """Views a run takes if every setpoint is reached: grid cells per arm times the arms, or
    the rows of the setpoint CSV; none without a renderer."""
    from agrisim.config import parse_grid

    if config.renderer.backend == "none":
        return 0
    if config.routine.csv is not None:
        lines = [ln for ln in config.routine.csv.read_text().splitlines() if ln.strip()]
        return max(len(lines) - 1, 0)
    levels, columns = parse_grid(config.routine.setpoints)
    return levels * columns * config.cell.arms


def _device(config: RunConfig, registry: Any, gpu: bool | None) -> str:
    """``gpu``, ``auto`` or ``cpu``: where the run's renderer draws (:class:`Cell`)."""
    if gpu is not None:
        return "gpu" if gpu else "cpu"
    if config.recon.backend == "splat":  # Gaussian splatting trains on a CUDA GPU only
        return "gpu"
    if config.renderer.backend == "none":
        return "cpu"
    spec = registry.get("renderer", config.renderer.backend)
    options = backend_options(spec.options_model, config.renderer.options_for(spec.name), "renderer")
    variant = getattr(options, "variant", None)
    return {"cuda": "gpu", "auto": "auto"}.get(str(variant), "cpu")


def _base(spec: SweepSpec, registry: Any) -> dict[str, Any]:
    """The spec's base configuration as every run shares it: no output folder of its own, and
    no recording unless the spec asks for one (a grid of recordings is rarely wanted)."""
    base = json.loads(json.dumps(spec.base, default=str))
    output = dict(base.get("output") or {})
    given = [k for k in OWN_OUTPUT if k in output]
    if given:
        raise UserError(f"{spec.path}: output.{given[0]}: the sweep puts every run in --out DIR itself")
    rerun = (base.get("sink") or {}).get("rerun") or {}
    for old, new in (("rrd", "path"), ("spawn", "spawn")):
        if output.get(old) or rerun.get(new):
            raise UserError(f"{spec.path}: a sweep runs many episodes: [sink.rerun] {new} cannot be shared by them")
    if "rerun" in registry.specs("sink") and "save" not in rerun and "no_rrd" not in output:
        set_dotted(base, "sink.rerun.save", False)
    return base


# A checklist in order, so that the first bad input is the one reported.
def plan_sweep(
    spec: SweepSpec, *, out: Path, overwrite: bool = False, resume: bool = False, registry: Any = None
) -> SweepPlan:
    """Validate every cell of the grid and plan its run; raises :class:`UserError` on bad
    input (an unknown setting or value in any cell, a bad output folder, under ``resume`` a
    run folder made with other settings), writing nothing."""
    from agrisim.registry import Registry, make_plugin_manager

    if overwrite and resume:
        raise UserError("--overwrite and --resume exclude each other")
    registry = registry if registry is not None else Registry(make_plugin_manager())
    out = Path(out).expanduser().absolute()  # absolute: Ray workers need not share our cwd
    base = _base(spec, registry)
    exporters = registry.specs("exporter")
    absent = [a for a in spec.after if a != "colmap" and a not in exporters]
    if absent:
        raise UserError(
            f"{spec.path}: [sweep] after names {absent[0]!r}, but no such exporter is installed "
            f"(installed: {', '.join(exporters) or 'none'})"
        )
    axes = list(spec.axes)
    grid = list(itertools.product(*(spec.axes[a] for a in axes)))
    names = cell_names(axes, grid)
    cells = []
    for name, values in zip(names, grid, strict=True):
        layer: dict[str, Any] = {}
        for key, value in zip(axes, values, strict=True):
            set_dotted(layer, key, value)
        run_dir = out / name
        try:
            config = build_config(base, layer, {"output": {"out": str(run_dir)}})
            check_run(registry, config, preflight=False)  # the cell runs elsewhere: its host checks the rest
            device = _device(config, registry, spec.gpu)
        except UserError as exc:
            raise UserError(f"sweep cell {name}: {exc}") from None
        action = _cell_action(run_dir, config, spec.after) if resume else "run"
        settings = dict(zip(axes, values, strict=True))
        cells.append(Cell(name, settings, run_dir, config.model_dump(mode="json"), device, _views(config), action))
    _check_out(out, overwrite=overwrite, resume=resume)
    return SweepPlan(spec=spec, out=out, cells=tuple(cells), overwrite=overwrite, resume=resume)


def _check_out(out: Path, *, overwrite: bool, resume: bool) -> None:
    """The output folder: a new or empty one, else ``--overwrite`` or ``--resume`` (of a sweep)."""
    from agrisim.plugins.apps.compare_plan import check_out as check_writable

    if resume and not (out / MANIFEST).is_file():
        raise OutputError(f"--resume: {out} holds no {MANIFEST}, so it is not a sweep to continue")
    if out.exists() and out.is_dir() and any(out.iterdir()) and not (overwrite or resume):
        raise OutputError(f"--out {out} already exists; pass --overwrite to replace it or --resume to continue it")
    check_writable(out, overwrite=True, resume=False)  # a directory, and writable


def follow_up_done(run_dir: Path, name: str) -> bool:
    """Has follow-up ``name`` finished on the run in ``run_dir`` (its last file written)?"""
    marker = {
        "colmap": Path(layout.COLMAP) / "poses.json",
        "coco": Path("coco") / "annotations.json",
        "nerfstudio": Path(layout.TRANSFORMS_JSON),
    }[name]
    return (run_dir / marker).is_file()


def _cell_action(run_dir: Path, config: RunConfig, after: Sequence[str]) -> str:
    """Under --resume: skip a complete run whose follow-ups are done, resume an unfinished one,
    run the rest; a run folder made with other settings is an error, never replaced or mixed."""
    state = run_dir_state(run_dir)
    if state in ("empty", "partial"):
        return "run"
    check_same_settings(run_dir, config, "this sweep")
    if state == "unfinished":
        return "resume"
    return "skip" if all(follow_up_done(run_dir, a) for a in after) else "after"


__all__ = [
    "COLMAP_OPTIONS",
    "FOLLOW_UPS",
    "MANIFEST",
    "Cell",
    "SweepPlan",
    "SweepSpec",
    "cell_names",
    "follow_up_done",
    "plan_sweep",
    "read_spec",
]
