"""``agrisim compare``: the paper's Table 2, texture labels ("Ours") against RepOpa, per plant.

For every plant and segmentation mode one episode runs, as a Ray task, into its own run
directory ``OUT/<plant>/<seg_mode>``; the table is then gathered from those directories'
``metrics.json`` files, never from what the tasks returned, so a table can always be rebuilt
from the files on disk. Outputs under ``OUT``:

``table.md``     the paper's Table 2 (labelled pixels and points, Ours vs RepOpa and
                 ``100 (RepOpa / Ours - 1)``) with accuracy columns added
``table.csv``    the same, one row per plant and label, every threshold
``chart.png``    bar charts of the same
``compare.json`` the plan (plants, modes, the base configuration), one record per episode
                 (Ray task id, worker pid, wall time, peak RSS) and the table's rows

The table itself (rows, markdown, CSV, chart) is :mod:`agrisim.app.table`.

The module is split into pure parts (planning and validating the episodes, building rows from
metrics dictionaries, formatting) and the parts with effects (:func:`execute` runs the Ray
tasks, :func:`write_outputs` writes the files). Ray and matplotlib are imported inside the
functions that need them, so ``import agrisim`` stays light.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import os
import resource
import shutil
import socket
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agrisim.files import layout
from agrisim.capabilities import check_renderer
from agrisim.kinds import SECTIONS
from agrisim.files.atomic import write_bytes, write_json
from agrisim.config import BackendChoice, RunConfig, backend_options, build_config, first_difference, merge, outcome_settings
from agrisim.errors import ConfigError, OutputError, UserError
from agrisim.app.table import (  # noqa: F401 - the table is part of compare's API
    is_file_plant,
    plant_key,
    SEG_MODES,
    MODE_TITLES,
    THRESHOLD_METRICS,
    TABLE_LABEL,
    read_metrics,
    percent_increase,
    table_rows,
    thresholds_of,
    table_threshold,
    plant_title,
    markdown_table,
    csv_table,
    chart_png,
)

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

    def to_json(self) -> dict[str, Any]:
        """The plan as ``compare.json`` records it."""
        return {
            "out": str(self.out),
            "plants": list(self.plants),
            "seg_modes": list(self.seg_modes),
            "base": self.base,
            "episodes": [
                {"plant": e.plant, "seg_mode": e.seg_mode, "run_dir": str(e.run_dir), "action": e.action}
                for e in self.episodes
            ],
        }


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
    _check_backends(registry, probe)
    renderer = registry.get("renderer", probe.renderer.backend)
    check_renderer(renderer, registry.specs("renderer"), seg_modes, probe.render.labels)

    out = Path(out).expanduser().absolute()  # absolute: Ray workers need not share our cwd
    _check_out(out, overwrite=overwrite, resume=resume)
    episodes = []
    for plant in plants:
        for mode in seg_modes:
            run_dir = out / plant_key(plant) / mode
            # a plant file by absolute path: a worker on another node need not share our cwd
            name = str(Path(plant).expanduser().absolute()) if is_file_plant(plant) else plant
            layer = {"plant": name, "render": {"seg_mode": mode}, "output": {"out": str(run_dir)}}
            try:
                config = build_config(shared, layer)
            except ConfigError as exc:
                raise UserError(f"{plant} ({mode}): {exc}") from None
            if plant in species:
                spec = species[plant]
                backend_options(spec.options_model, config.plants.get(plant, {}), f"plant {plant!r}")
            action = _episode_action(run_dir, config) if resume else "run"
            if action == "resume":
                config = config.model_copy(update={"output": config.output.model_copy(update={"resume": True})})
            elif action == "run" and resume and run_dir.exists() and any(run_dir.iterdir()):
                # leftovers without a run.json (killed before its first write): nothing finished
                config = config.model_copy(update={"output": config.output.model_copy(update={"overwrite": True})})
            episodes.append(EpisodePlan(plant, mode, run_dir, config.model_dump(mode="json"), action))
    return ComparePlan(
        out=out,
        plants=plants,
        seg_modes=seg_modes,
        episodes=tuple(episodes),
        base=json.loads(json.dumps(shared, default=str)),
        overwrite=overwrite,
        resume=resume,
    )


def _check_backends(registry: Any, config: RunConfig) -> None:
    """Every chosen backend exists and its options validate (the workers would fail late)."""
    for name, kind in SECTIONS.items():
        choice = getattr(config, name, None)
        if not isinstance(choice, BackendChoice) or choice.backend == "none":
            continue
        spec = registry.get(kind, choice.backend)
        backend_options(spec.options_model, choice.options_for(spec.name), f"{kind} backend {spec.name!r}")


def _check_out(out: Path, *, overwrite: bool, resume: bool) -> None:
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
    saved = json.loads((run_dir / layout.RUN_JSON).read_text()).get("config") or {}
    diff = first_difference(outcome_settings(build_config(saved)), outcome_settings(config))
    if diff is not None:
        key, was, now = diff
        raise OutputError(
            f"--resume: {run_dir} was run with {key} = {was!r}, this compare asks for {now!r}; "
            "give the same settings, or --overwrite"
        )
    return "skip" if state == "complete" else "resume"


# ---------------------------------------------------------------------------------- running


def run_episode_task(config: Mapping[str, Any]) -> dict[str, Any]:
    """Run one episode from its configuration (JSON); the body of each Ray task.

    Returns a record of where and how it ran: Ray task id, worker pid and node, status, wall
    time and memory. Failures are caught and recorded, so one bad episode does not cost the
    others; the numbers of the table are read from the run directory afterwards.
    """
    t0 = time.perf_counter()
    record: dict[str, Any] = {
        "plant": config.get("plant"),
        "seg_mode": (config.get("render") or {}).get("seg_mode"),
        "run_dir": (config.get("output") or {}).get("out"),
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "rss_start_mb": _rss_mb(),
    }
    try:
        import ray

        if ray.is_initialized():
            ctx = ray.get_runtime_context()
            record.update(task_id=ctx.get_task_id(), worker_id=ctx.get_worker_id(), node_id=ctx.get_node_id())
    except ImportError:  # pragma: no cover - called outside Ray (tests, debugging)
        pass
    try:
        from agrisim.episode import Episode

        record["import_s"] = round(time.perf_counter() - t0, 3)  # a fresh worker pays this per episode
        run, summary = Episode(build_config(config)).run()
        record.update(status=summary.status, setpoints=summary.setpoints, reached=summary.reached, error=summary.error)
    except UserError as exc:
        record.update(status="error", error=str(exc))
    except Exception as exc:  # an internal failure of this episode; the others go on
        record.update(status="failed", error=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc())
    record["wall_s"] = round(time.perf_counter() - t0, 3)
    record["rss_end_mb"] = _rss_mb()
    # ru_maxrss is KiB on Linux: the worker's peak, which with max_calls=1 is this episode's
    record["rss_peak_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    return record


def _rss_mb() -> float | None:
    """Resident memory of this process now, MB (None where /proc is missing)."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return round(pages * os.sysconf("SC_PAGE_SIZE") / 2**20, 1)
    except (OSError, ValueError, IndexError):  # pragma: no cover
        return None


@dataclass
class ExecuteResult:
    """What :func:`execute` did: a record per episode (plan order) and Ray's figures."""

    records: list[dict[str, Any]]
    ray: dict[str, Any] = field(default_factory=dict)
    interrupted: bool = False


def start_ray(*, workers: int | None, address: str | None) -> dict[str, Any]:
    """Start a quiet local Ray with ``workers`` CPUs, or join the cluster at ``address``.

    Returns facts for ``compare.json``: address, CPUs, start-up time, and ``owned``: whether
    :func:`stop_ray` shuts it down (a Ray the caller had initialised already is used as it is,
    and left running). An unreachable address is a :class:`UserError`; it is probed first,
    because Ray itself retries for minutes.
    """
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no usage report from a batch tool
    import ray

    if ray.is_initialized():  # e.g. compare called from a notebook that has its own Ray
        return {"address": "existing", "cluster_cpus": ray.cluster_resources().get("CPU"),
                "nodes": len(ray.nodes()), "startup_s": 0.0, "ray": ray.__version__, "owned": False}
    if address not in (None, "auto", "local") and not address.startswith("ray://"):
        _probe(address)
    common: dict[str, Any] = dict(
        include_dashboard=False,
        log_to_driver=False,  # episodes' own output would tear the progress bar
        logging_level=logging.ERROR,
        configure_logging=True,
    )
    t0 = time.perf_counter()
    try:
        if address in (None, "local"):
            # A private local cluster ("local": never a RAY_ADDRESS from the environment), bound
            # to loopback, with a small object store: tasks return only small records.
            ray.init(
                address="local",
                num_cpus=workers or os.cpu_count() or 1,
                object_store_memory=128 * 2**20,
                _node_ip_address="127.0.0.1",
                **common,
            )
        else:
            ray.init(address=address, **common)
    except (ConnectionError, TimeoutError) as exc:
        hint = ""
        if "Authentication" in type(exc.__cause__).__name__:
            hint = "; the cluster uses token authentication: set RAY_AUTH_MODE=token and its token"
        raise UserError(f"--ray-address {address}: cannot join a Ray cluster there ({exc}{hint})") from None
    startup = time.perf_counter() - t0
    resources = ray.cluster_resources()
    return {
        "address": address or "local",
        "cluster_cpus": resources.get("CPU"),
        "nodes": len(ray.nodes()),
        "startup_s": round(startup, 3),
        "ray": ray.__version__,
        "owned": True,
    }


def stop_ray(info: dict[str, Any]) -> None:
    """Shut down the Ray that :func:`start_ray` started (not one it found running)."""
    import ray

    t0 = time.perf_counter()
    if info.get("owned"):
        ray.shutdown()
    info["shutdown_s"] = round(time.perf_counter() - t0, 3)


def _probe(address: str, timeout: float = 5.0) -> None:
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit():
        raise UserError(f"--ray-address expects HOST:PORT, 'auto' or ray://HOST:PORT, got {address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise UserError(f"--ray-address {address}: cannot reach a Ray cluster there ({exc.strerror or exc})") from None


def execute(
    plan: ComparePlan,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    result: ExecuteResult | None = None,
    ray_info: dict[str, Any] | None = None,
) -> ExecuteResult:
    """Run the plan's episodes as Ray tasks, at most ``workers`` at a time; shut Ray down.

    Each task runs in a fresh worker process (``max_calls=1``): an episode's memory (plant,
    scene, Embree BVH, pybullet) is returned to the system when it ends, so twenty episodes
    cost no more than the largest one, and nothing one episode leaves in a process can change
    the next one's result. Tasks are not retried: a crashed episode leaves a partial run
    directory that ``--resume`` continues. Skipped episodes (``--resume``, complete) get a
    record without running. ``result``, when given, is filled in as tasks finish, so a caller
    still has the finished episodes' records after an interruption. ``ray_info``, when given,
    says the caller has started Ray already (:func:`start_ray`); Ray is shut down here either way.
    """
    result = result if result is not None else ExecuteResult([])
    records: dict[int, dict[str, Any]] = {}

    def _collect() -> None:
        result.records = [
            records.get(i, {"plant": e.plant, "seg_mode": e.seg_mode, "run_dir": str(e.run_dir), "status": "not run"})
            for i, e in enumerate(plan.episodes)
        ]

    for i, e in enumerate(plan.episodes):
        if e.action == "skip":
            records[i] = {"plant": e.plant, "seg_mode": e.seg_mode, "run_dir": str(e.run_dir),
                          "status": "skipped", "action": "skip"}
    queue = [(i, e) for i, e in enumerate(plan.episodes) if e.action != "skip"]
    total, done = len(plan.episodes), len(records)
    if progress:
        progress(done, total)
    _collect()
    if not queue:
        return result

    import ray

    result.ray = ray_info if ray_info is not None else start_ray(workers=workers, address=ray_address)
    pending: dict[Any, tuple[int, EpisodePlan, float]] = {}
    try:
        task = ray.remote(num_cpus=1, max_calls=1, max_retries=0)(run_episode_task)
        limit = workers or len(queue)
        t0 = time.perf_counter()
        while queue or pending:
            while queue and len(pending) < limit:
                i, e = queue.pop(0)
                pending[task.remote(e.config)] = (i, e, time.perf_counter() - t0)
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                i, e, submitted = pending.pop(ref)
                try:
                    rec = ray.get(ref)
                except ray.exceptions.RayError as exc:  # the worker died (OOM killer, segfault)
                    first = (str(exc).strip().splitlines() or [""])[0]
                    rec = {"plant": e.plant, "seg_mode": e.seg_mode, "run_dir": str(e.run_dir),
                           "status": "failed", "error": f"{type(exc).__name__}: {first}"}
                rec["action"] = e.action
                rec["submitted_s"] = round(submitted, 3)
                rec["finished_s"] = round(time.perf_counter() - t0, 3)
                rec["driver_rss_mb"] = _rss_mb()  # the driver must stay flat while records pile up
                records[i] = rec
                _collect()
                done += 1
                if progress:
                    progress(done, total)
    except KeyboardInterrupt:
        result.interrupted = True
        for ref, (i, e, _) in pending.items():
            ray.cancel(ref, force=True)
            records[i] = {"plant": e.plant, "seg_mode": e.seg_mode, "run_dir": str(e.run_dir),
                          "status": "cancelled", "action": e.action}
        raise
    finally:
        _collect()
        stop_ray(result.ray)
    return result


# ---------------------------------------------------------------------------------- the table


def gather(plan: ComparePlan) -> tuple[list[dict[str, Any]], list[str]]:
    """The table's rows read from the run directories' ``metrics.json``, and the episodes that
    have none (as ``plant (mode)`` strings)."""
    metrics: dict[tuple[str, str], dict[str, Any] | None] = {}
    missing = []
    for e in plan.episodes:
        doc = read_metrics(e.run_dir)
        metrics[(e.plant, e.seg_mode)] = doc
        if doc is None:
            missing.append(f"{e.plant} ({e.seg_mode})")
    return table_rows(metrics, plan.plants, plan.seg_modes, per_label=True), missing


def write_outputs(
    plan: ComparePlan, rows: Sequence[Mapping[str, Any]], report: Mapping[str, Any]
) -> dict[str, Path]:
    """Write ``table.md``, ``table.csv``, ``chart.png`` and ``compare.json`` under the plan's
    ``out`` (each atomically); returns their paths by kind."""
    out = plan.out
    names = {"md": "table.md", "csv": "table.csv", "png": "chart.png", "json": "compare.json"}
    paths = {k: out / n for k, n in names.items()}
    write_bytes(paths["md"], markdown_table(rows, plan.seg_modes).encode())
    write_bytes(paths["csv"], csv_table(rows, plan.seg_modes).encode())
    write_bytes(paths["png"], chart_png(rows, plan.seg_modes, title="Ours (texture labels) vs RepOpa"))
    write_json(paths["json"], {**report, "rows": list(rows)})
    return paths


def prepare_out(plan: ComparePlan) -> None:
    """Create ``out``; under --overwrite replace what was there (checked by the plan)."""
    if plan.overwrite and plan.out.exists():
        shutil.rmtree(plan.out)
    try:
        plan.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create --out {plan.out}: {exc}") from None


@dataclass
class CompareResult:
    """The outcome of :func:`compare`."""

    plan: ComparePlan
    rows: list[dict[str, Any]]
    records: list[dict[str, Any]]
    missing: list[str]
    paths: dict[str, Path]
    wall_s: float
    ray: dict[str, Any]

    @property
    def failed(self) -> list[dict[str, Any]]:
        """Records of episodes that did not complete."""
        return [r for r in self.records if r.get("status") not in ("complete", "skipped")]


def compare(
    plan: ComparePlan,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> CompareResult:
    """Run a planned compare: prepare ``out``, run the episodes on Ray, gather the table from
    the run directories and write it. ``compare.json`` is written first (status running) and
    last; an interrupted compare leaves it saying so, and ``--resume`` continues it."""
    t0 = time.perf_counter()
    report: dict[str, Any] = {
        "agrisim_compare": 1,
        "status": "running",
        "started_at": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command": sys.argv,
        "workers": workers,
        "ray_address": ray_address,
        "plan": plan.to_json(),
    }
    # Ray first: an unreachable --ray-address is bad input, found before anything is written.
    todo = any(e.action != "skip" for e in plan.episodes)
    ray_info = start_ray(workers=workers, address=ray_address) if todo else None
    try:
        prepare_out(plan)
        write_json(plan.out / "compare.json", report)
    except BaseException:
        if ray_info is not None:
            stop_ray(ray_info)
        raise
    status = "interrupted"
    executed = ExecuteResult([])
    try:
        execute(plan, workers=workers, ray_address=ray_address, progress=progress, result=executed, ray_info=ray_info)
        status = "complete"
    finally:
        rows, missing = gather(plan)
        unfinished = [r for r in executed.records if r.get("status") not in ("complete", "skipped")]
        if status == "complete" and (missing or unfinished):
            status = "incomplete"
        wall = time.perf_counter() - t0
        report.update(status=status, wall_s=round(wall, 3), ray=executed.ray, episodes=executed.records,
                      missing_metrics=missing)
        paths = write_outputs(plan, rows, report)
    return CompareResult(plan, rows, executed.records, missing, paths, wall, executed.ray)


__all__ = [
    "PAPER_PLANTS",
    "SEG_MODES",
    "ComparePlan",
    "CompareResult",
    "EpisodePlan",
    "compare",
    "csv_table",
    "chart_png",
    "execute",
    "gather",
    "markdown_table",
    "parse_names",
    "percent_increase",
    "plan_compare",
    "read_metrics",
    "run_dir_state",
    "run_episode_task",
    "table_rows",
    "write_outputs",
]
