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

The table itself (rows, markdown, CSV, chart) is :mod:`agrisim.plugins.apps.table`.

The module is split into pure parts (planning and validating the episodes, building rows from
metrics dictionaries, formatting) and the parts with effects (:func:`execute` runs the Ray
tasks, :func:`write_outputs` writes the files). Ray and matplotlib are imported inside the
functions that need them, so ``import agrisim`` stays light.
"""

from __future__ import annotations

import datetime as _dt
import logging
import os
import resource
import shutil
import socket
import sys
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agrisim.config import build_config
from agrisim.errors import OutputError, UserError
from agrisim.files.atomic import write_bytes, write_json
from agrisim.plugins.apps.batch import first_line, run_batch
from agrisim.plugins.apps.compare_plan import (  # noqa: F401 - planning is part of compare's API
    PAPER_PLANTS,
    ComparePlan,
    EpisodePlan,
    default_out,
    parse_names,
    plan_compare,
    run_dir_state,
)
from agrisim.plugins.apps.point_table import point_chart_png, point_csv, point_markdown, point_rows
from agrisim.plugins.apps.table import (  # noqa: F401 - the table is part of compare's API
    MODE_TITLES,
    SEG_MODES,
    TABLE_LABEL,
    THRESHOLD_METRICS,
    chart_png,
    csv_table,
    is_file_plant,
    markdown_table,
    percent_increase,
    plant_key,
    plant_title,
    read_metrics,
    table_rows,
    table_threshold,
    thresholds_of,
)

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
        return {
            "address": "existing",
            "cluster_cpus": ray.cluster_resources().get("CPU"),
            "nodes": len(ray.nodes()),
            "startup_s": 0.0,
            "ray": ray.__version__,
            "owned": False,
        }
    if address not in (None, "auto", "local") and not address.startswith("ray://"):
        probe(address)
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


def probe(address: str, timeout: float = 5.0) -> None:
    """Refuse a ``--ray-address`` that is not HOST:PORT or where nothing listens."""
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit():
        raise UserError(f"--ray-address expects HOST:PORT, 'auto' or ray://HOST:PORT, got {address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise UserError(f"--ray-address {address}: cannot reach a Ray cluster there ({exc.strerror or exc})") from None


# Long because Ray's submit/wait/interrupt loop shares its state (pending tasks, records,
# progress); split, that state would travel between functions.
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
        result.records = [records.get(i, {**_stub(e), "status": "not run"}) for i, e in enumerate(plan.episodes)]

    for i, e in enumerate(plan.episodes):
        if e.action == "skip":
            records[i] = {**_stub(e), "status": "skipped", "action": "skip"}
    queue = [(i, e) for i, e in enumerate(plan.episodes) if e.action != "skip"]
    total, done = len(plan.episodes), len(records)
    if progress:
        progress(done, total)
    _collect()
    if not queue:
        return result

    import ray

    result.ray = ray_info if ray_info is not None else start_ray(workers=workers, address=ray_address)
    task = ray.remote(num_cpus=1, max_calls=1, max_retries=0)(run_episode_task)
    t0 = time.perf_counter()
    submitted: dict[int, float] = {}

    def submit(item: tuple[int, EpisodePlan]) -> Any:
        submitted[item[0]] = time.perf_counter() - t0
        return task.remote(item[1].config)

    def finished(item: tuple[int, EpisodePlan], rec: Any, error: BaseException | None) -> None:
        nonlocal done
        i, e = item
        if error is not None:  # the worker died (OOM killer, segfault)
            rec = {**_stub(e), "status": "failed", "error": first_line(error)}
        rec["action"] = e.action
        rec["submitted_s"] = round(submitted[i], 3)
        rec["finished_s"] = round(time.perf_counter() - t0, 3)
        rec["driver_rss_mb"] = _rss_mb()  # the driver must stay flat while records pile up
        records[i] = rec
        _collect()
        done += 1
        if progress:
            progress(done, total)

    def cancelled(item: tuple[int, EpisodePlan]) -> None:
        records[item[0]] = {**_stub(item[1]), "status": "cancelled", "action": item[1].action}

    try:
        run_batch(queue, submit, finished, limits={None: workers or len(queue)}, cancelled=cancelled)
    except KeyboardInterrupt:
        result.interrupted = True
        raise
    finally:
        _collect()
        stop_ray(result.ray)
    return result


def _stub(e: EpisodePlan) -> dict[str, Any]:
    """An episode's record before it has one of its own: what it is and where it goes."""
    return {"plant": e.plant, "seg_mode": e.seg_mode, **_variant(e), "run_dir": str(e.run_dir)}


# ---------------------------------------------------------------------------------- the table


def gather(plan: ComparePlan) -> tuple[list[dict[str, Any]], list[str]]:
    """The table's rows read from the run directories' ``metrics.json``, and the episodes that
    have none (as ``plant (mode)`` strings)."""
    metrics: dict[tuple[str, str], dict[str, Any] | None] = {}
    missing = []
    for e in plan.episodes:
        doc = read_metrics(e.run_dir)
        metrics[(e.plant, e.key)] = doc
        if doc is None:
            missing.append(f"{e.plant} ({e.key})")
    if plan.point_sizes:
        return point_rows(metrics, plan.plants, plan.variants, plan.as_points), missing
    return table_rows(metrics, plan.plants, plan.seg_modes, per_label=True), missing


def _variant(e: EpisodePlan) -> dict[str, str]:
    """A Table 3 episode's variant for its record (Table 2's records stay as they were)."""
    return {"variant": e.variant} if e.variant else {}


def write_outputs(plan: ComparePlan, rows: Sequence[Mapping[str, Any]], report: Mapping[str, Any]) -> dict[str, Path]:
    """Write ``table.md``, ``table.csv``, ``chart.png`` and ``compare.json`` under the plan's
    ``out`` (each atomically); returns their paths by kind."""
    out = plan.out
    names = {"md": "table.md", "csv": "table.csv", "png": "chart.png", "json": "compare.json"}
    paths = {k: out / n for k, n in names.items()}
    if plan.point_sizes:
        write_bytes(paths["md"], point_markdown(rows).encode())
        write_bytes(paths["csv"], point_csv(rows).encode())
        write_bytes(paths["png"], point_chart_png(rows))
    else:
        write_bytes(paths["md"], markdown_table(rows, plan.seg_modes).encode())
        write_bytes(paths["csv"], csv_table(rows, plan.seg_modes).encode())
        write_bytes(paths["png"], chart_png(rows, plan.seg_modes, title="Ours (texture labels) vs RepOpa"))
    write_json(paths["json"], {**report, "rows": list(rows)})
    return paths


def prepare_out(out: Path, overwrite: bool) -> None:
    """Create ``out`` (of a compare or a sweep); with ``overwrite`` replace what was there
    (the plan checked that it may)."""
    if overwrite and out.exists():
        shutil.rmtree(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create --out {out}: {exc}") from None


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
        prepare_out(plan.out, plan.overwrite)
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
        report.update(
            status=status, wall_s=round(wall, 3), ray=executed.ray, episodes=executed.records, missing_metrics=missing
        )
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
