"""Planning a compare: every episode's configuration built and validated, the output
directory and any earlier run directories checked, all before Ray starts or anything is
written (:func:`plan_compare`)."""

from __future__ import annotations

import datetime as _dt
import json
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agrisim.capabilities import check_renderer
from agrisim.config import (
    RunConfig,
    backend_options,
    build_config,
    first_difference,
    merge,
    outcome_settings,
)
from agrisim.errors import ConfigError, OutputError, UserError
from agrisim.files import layout
from agrisim.plugins.apps.table import SEG_MODES, is_file_plant, plant_key
from agrisim.validation import check_run

#: the ten procedural species, in the row order of the paper's Table 2
PAPER_PLANTS: tuple[str, ...] = (
    "hydrangea",
    "indian_cress",
    "amaryllis",
    "boston_fern",
    "common_fern",
    "bog_marshcress",
    "boxwood",
    "coltsfoot",
    "chinese_evergreen",
    "basket_grass",
)


# ---------------------------------------------------------------------------------- planning


@dataclass(frozen=True)
class EpisodePlan:
    """One episode of a compare: a plant in one segmentation mode, with its run directory.

    ``action`` says what :func:`execute` does with it: ``run`` (a new run directory),
    ``resume`` (continue the unfinished run in it) or ``skip`` (complete already, --resume).
    """

    plant: str
    seg_mode: str
    run_dir: Path
    config: dict[str, Any]  # the RunConfig as JSON, what the Ray task receives
    action: str = "run"
    variant: str = ""
    """Table 3's episodes: ``mesh`` (the plant as it is) or the point size in metres (``%g``);
    empty for Table 2's, which differ by ``seg_mode`` alone."""

    @property
    def key(self) -> str:
        """What tells this episode from the plant's others: its variant, else its mode."""
        return self.variant or self.seg_mode


@dataclass(frozen=True)
class ComparePlan:
    """Everything a compare will do, validated; building it writes nothing."""

    out: Path
    plants: tuple[str, ...]
    seg_modes: tuple[str, ...]
    episodes: tuple[EpisodePlan, ...]
    base: dict[str, Any]  # the layered settings every episode shares (JSON)
    overwrite: bool = False
    resume: bool = False
    as_points: int | None = None
    point_sizes: tuple[float, ...] = ()
    """Table 3 (``--point-sizes``): one episode per size after the mesh's own."""

    @property
    def variants(self) -> tuple[str, ...]:
        """The row keys of a Table 3 compare (``mesh``, then each size), or the modes."""
        if self.point_sizes:
            return ("mesh", *(size_key(s) for s in self.point_sizes))
        return self.seg_modes

    def to_json(self) -> dict[str, Any]:
        """The plan as ``compare.json`` records it."""
        return {
            "out": str(self.out),
            "plants": list(self.plants),
            "seg_modes": list(self.seg_modes),
            "base": self.base,
            "as_points": self.as_points,
            "point_sizes": list(self.point_sizes),
            "episodes": [
                {
                    "plant": e.plant,
                    "seg_mode": e.seg_mode,
                    "variant": e.variant,
                    "run_dir": str(e.run_dir),
                    "action": e.action,
                }
                for e in self.episodes
            ],
        }


def size_key(size: float) -> str:
    """A point size as Table 3's rows and run directories name it (metres, ``%g``)."""
    return f"{size:g}"


def parse_sizes(text: str | None) -> list[float] | None:
    """``--point-sizes "0.001,0.002"`` -> sizes in metres, each checked (finite, > 0)."""
    from agrisim.scene.points import check_size

    if text is None:
        return None
    sizes = []
    for item in text.split(","):
        try:
            value = float(item)
        except ValueError:
            raise UserError(
                f"--point-sizes expects comma-separated sizes in metres (e.g. 0.001,0.002), got {item.strip()!r}"
            ) from None
        check_size(value, "--point-sizes")
        sizes.append(value)
    keys = [size_key(v) for v in sizes]
    if len(set(keys)) != len(keys):
        raise UserError(f"--point-sizes names a size more than once: {text}")
    return sizes


def parse_names(text: str | None, what: str, allowed: Iterable[str] | None = None) -> list[str] | None:
    """``"a,b"`` -> ``["a", "b"]`` (None stays None). Empty items, duplicates and, when
    ``allowed`` is given, unknown names are a :class:`UserError` listing what is allowed."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",")]
    if not all(names):
        raise UserError(f"--{what} expects comma-separated names, got {text!r}")
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise UserError(f"--{what} names {', '.join(dupes)} more than once")
    if allowed is not None:
        allowed = list(allowed)
        unknown = [n for n in names if n not in allowed]
        if unknown:
            raise UserError(f"--{what}: unknown {', '.join(map(repr, unknown))}; allowed: {', '.join(allowed)}")
    return names


def default_out() -> Path:
    """``runs/compare-<timestamp>``, beside the runs of ``agrisim run``."""
    return Path("runs") / _dt.datetime.now().strftime("compare-%Y%m%d-%H%M%S")


# A checklist in order, a few lines per check, so that the first bad input is the one reported.
def plan_compare(
    base: Mapping[str, Any],
    *,
    out: Path,
    plants: Sequence[str] | None = None,
    seg_modes: Sequence[str] | None = None,
    overwrite: bool = False,
    resume: bool = False,
    recordings: bool = False,
    registry: Any = None,
    as_points: int | None = None,
    point_sizes: Sequence[float] | None = None,
) -> ComparePlan:
    """Validate a compare and plan its episodes; raises :class:`UserError` on bad input.

    ``base`` is the layered settings (TOML file and flags) every episode shares; compare sets
    ``plant``, ``render.seg_mode`` and the ``output`` table of each episode itself. Recordings
    are off unless ``recordings`` or the settings ask for them (twenty ``.rrd`` files are
    rarely wanted). Everything is checked here, before Ray starts or anything is written:
    plant and backend names, every episode's configuration, the output directory, and under
    ``resume`` that each existing run directory was made with the same settings.
    """
    from agrisim.registry import Registry, make_plugin_manager

    if overwrite and resume:
        raise UserError("--overwrite and --resume exclude each other")
    sizes = tuple(point_sizes or ())
    if sizes:  # the paper's Table 3: the mesh, then its points at each size, in its own mode
        if as_points is None:
            raise UserError("--point-sizes draws the plants as points: give --as-points N too")
        from agrisim.scene.points import check_count

        check_count(as_points)
        if seg_modes and tuple(seg_modes) != ("texture",):
            raise UserError(
                "--point-sizes compares point sizes in the paper's segmentation mode: leave out --seg-modes"
            )
        seg_modes = ("texture",)
    elif as_points is not None:
        raise UserError("--as-points in a compare needs --point-sizes (one episode per size)")
    seg_modes = tuple(seg_modes or SEG_MODES)
    bad = [m for m in seg_modes if m not in SEG_MODES]
    if bad:
        raise UserError(f"--seg-modes: unknown {', '.join(map(repr, bad))}; allowed: {', '.join(SEG_MODES)}")
    registry = registry if registry is not None else Registry(make_plugin_manager())
    base = dict(base)
    # The recording's settings, as flags (output.rrd, .spawn, .no_rrd) or as [sink.rerun]
    output = dict(base.get("output") or {})
    rerun = dict((base.get("sink") or {}).get("rerun") or {})
    for flag, old, new in (("--rrd", "rrd", "path"), ("--spawn", "spawn", "spawn")):
        if output.get(old) or rerun.get(new):
            raise UserError(
                f"compare runs many episodes: {flag} ([sink.rerun] {new}) cannot be shared by them "
                "(with --recordings each run directory gets its own recording.rrd)"
            )
    save = recordings or rerun.get("save") is True or output.get("no_rrd") is False
    base["output"] = {k: v for k, v in output.items() if k not in ("out", "overwrite", "resume", "no_rrd")}
    base.pop("plant", None)
    if isinstance(base.get("render"), Mapping):
        base["render"] = {k: v for k, v in base["render"].items() if k != "seg_mode"}
    shared = dict(base)
    if "rerun" in registry.specs("sink"):
        shared = merge(base, {"sink": {"rerun": {"save": save}}})
    try:
        probe = build_config(shared)  # the shared settings alone: one clear error, not twenty
    except ConfigError as exc:
        raise UserError(str(exc)) from None
    if probe.renderer.backend == "none":
        raise UserError("compare counts labelled pixels: it needs a renderer (raycast or pybullet), not 'none'")

    species = registry.specs("plant")
    plants = tuple(plants) if plants else PAPER_PLANTS
    for plant in plants:
        if plant not in species and not is_file_plant(plant):
            raise UserError(
                f"unknown plant {plant!r}; species: {', '.join(species) or 'none installed'}; or a .glb/.gltf/.obj file"
            )
        if is_file_plant(plant) and not Path(plant).is_file():
            raise UserError(f"plant file not found: {plant}")
    keys = [plant_key(p) for p in plants]
    clash = sorted({k for k in keys if keys.count(k) > 1})
    if clash:
        raise UserError(f"--plants: two plants would share the run directory {clash[0]!r}")
    renderer = registry.get("renderer", probe.renderer.backend)
    check_renderer(renderer, registry.specs("renderer"), seg_modes, probe.render.labels, points=bool(sizes))
    check_run(registry, probe, preflight=False)  # what each episode will check, but what only its host can
    if sizes and "points" in base:
        raise UserError("--point-sizes sets each episode's points: leave [points] out of the shared settings")

    out = Path(out).expanduser().absolute()  # absolute: Ray workers need not share our cwd
    check_out(out, overwrite=overwrite, resume=resume)
    episodes = []
    # (mode, variant, run-directory name, settings of its own) of each plant's episodes
    variants: list[tuple[str, str, str, dict[str, Any]]] = [(m, "", m, {}) for m in seg_modes]
    if sizes:
        variants = [("texture", "mesh", "mesh", {})] + [
            ("texture", size_key(s), f"points-{size_key(s)}", {"points": {"count": as_points, "size": s}})
            for s in sizes
        ]
    for plant in plants:
        for mode, variant, folder, extra in variants:
            run_dir = out / plant_key(plant) / folder
            # a plant file by absolute path: a worker on another node need not share our cwd
            name = str(Path(plant).expanduser().absolute()) if is_file_plant(plant) else plant
            layer = {"plant": name, "render": {"seg_mode": mode}, "output": {"out": str(run_dir)}, **extra}
            try:
                config = build_config(shared, layer)
            except ConfigError as exc:
                raise UserError(f"{plant} ({variant or mode}): {exc}") from None
            if plant in species:
                spec = species[plant]
                backend_options(spec.options_model, config.plants.get(plant, {}), f"plant {plant!r}")
            action = _episode_action(run_dir, config) if resume else "run"
            if action == "resume":
                config = config.model_copy(update={"output": config.output.model_copy(update={"resume": True})})
            elif action == "run" and resume and run_dir.exists() and any(run_dir.iterdir()):
                # leftovers without a run.json (killed before its first write): nothing finished
                config = config.model_copy(update={"output": config.output.model_copy(update={"overwrite": True})})
            episodes.append(EpisodePlan(plant, mode, run_dir, config.model_dump(mode="json"), action, variant))
    return ComparePlan(
        out=out,
        plants=plants,
        seg_modes=seg_modes,
        episodes=tuple(episodes),
        base=json.loads(json.dumps(shared, default=str)),
        overwrite=overwrite,
        resume=resume,
        as_points=as_points,
        point_sizes=sizes,
    )


def check_out(out: Path, *, overwrite: bool, resume: bool) -> None:
    """A compare's output folder: new or empty, else ``--overwrite`` or ``--resume`` (of a
    compare); a directory, and writable."""
    if out.exists():
        if not out.is_dir():
            raise OutputError(f"--out {out} exists and is not a directory")
        if any(out.iterdir()):
            if resume and not (out / "compare.json").is_file():
                raise OutputError(f"--resume: {out} holds no compare.json, so it is not a compare to continue")
            if not (overwrite or resume):
                raise OutputError(
                    f"--out {out} already exists; pass --overwrite to replace it or --resume to continue it"
                )
    parent = out
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"--out {out} is not writable ({parent} does not allow creating files)")


def run_dir_state(run_dir: Path) -> str:
    """What lies in an episode's run directory: ``empty`` (absent or empty), ``partial``
    (files but no readable run.json), ``unfinished`` (run.json not complete), ``complete``
    (run.json complete and metrics.json present) or ``complete-no-metrics``."""
    if not run_dir.is_dir() or not any(run_dir.iterdir()):
        return "empty"
    try:
        doc = json.loads((run_dir / layout.RUN_JSON).read_text())
    except (OSError, ValueError):
        return "partial"
    if not isinstance(doc, dict) or doc.get("status") != "complete":
        return "unfinished"
    return "complete" if (run_dir / layout.METRICS_JSON).is_file() else "complete-no-metrics"


def _episode_action(run_dir: Path, config: RunConfig) -> str:
    """Under --resume: skip a complete run, resume an unfinished one, run the rest; a run
    directory made with other settings is an error, never silently replaced or mixed."""
    state = run_dir_state(run_dir)
    if state in ("empty", "partial"):
        return "run"
    if state == "complete-no-metrics":
        raise OutputError(
            f"--resume: {run_dir} is a complete run without metrics.json; pass --overwrite to run the compare again"
        )
    check_same_settings(run_dir, config, "this compare")
    return "skip" if state == "complete" else "resume"


def check_same_settings(run_dir: Path, config: RunConfig, asker: str) -> None:
    """Under --resume: an OutputError where the run in ``run_dir`` was made with settings that
    change its outcome from ``config``'s (``asker`` names who asks, in the message)."""
    saved = json.loads((run_dir / layout.RUN_JSON).read_text()).get("config") or {}
    diff = first_difference(outcome_settings(build_config(saved)), outcome_settings(config))
    if diff is not None:
        key, was, now = diff
        raise OutputError(
            f"--resume: {run_dir} was run with {key} = {was!r}, {asker} asks for {now!r}; "
            "give the same settings, or --overwrite"
        )
