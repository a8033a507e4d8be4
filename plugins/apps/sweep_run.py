"""Running a planned sweep (:mod:`agrisim.plugins.apps.sweep`) on Ray: every cell a task in a fresh
worker, GPU runs one per GPU, CPU runs one per core, locally or on a cluster.

Each task decides what to do from the cell's folder as it finds it (:func:`run_cell_task`):
a complete run is kept, an unfinished one resumed (``agrisim run --resume``), leftovers without
a ``run.json`` replaced, an empty folder run; then the follow-ups not done yet. So a task that
Ray retries after its worker died (``max_retries``) continues where the lost one stopped, and
nothing complete is redone. ``OUT/sweep.json`` is rebuilt from the run folders whenever a task
ends, and written first (status running) and last.
"""

from __future__ import annotations

import datetime as _dt
import os
import socket
import sys
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from agrisim.config import build_config
from agrisim.errors import UserError
from agrisim.files import layout
from agrisim.files.atomic import write_json
from agrisim.plugins.apps.batch import first_line, run_batch
from agrisim.plugins.apps.compare import prepare_out, probe, start_ray, stop_ray
from agrisim.plugins.apps.compare_plan import run_dir_state
from agrisim.plugins.apps.placement import task_resources
from agrisim.plugins.apps.sweep import MANIFEST, Cell, SweepPlan, follow_up_done

#: Ray retries a task whose worker or node was lost this many times (an exception raised by
#: the run itself is recorded, never retried: it would fail the same way)
MAX_RETRIES = 3

# ---------------------------------------------------------------------------------- one cell


def run_cell_task(config: Mapping[str, Any], after: Sequence[str], colmap: Mapping[str, Any]) -> dict[str, Any]:
    """One cell in a Ray worker: its run from where its folder stands, then its follow-ups.

    Returns a record of where and how it ran (pid, host, node, the resources Ray assigned,
    start and end times, the action taken, each follow-up's outcome); the figures of the
    manifest are read from the run folder afterwards, never from here.
    """
    t0 = time.perf_counter()
    run_dir = Path(config["output"]["out"])
    record: dict[str, Any] = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time()}
    try:
        import ray

        if ray.is_initialized():
            ctx = ray.get_runtime_context()
            record.update(node_id=ctx.get_node_id(), resources=ctx.get_assigned_resources())
    except ImportError:  # pragma: no cover - called outside Ray (debugging)
        pass
    try:
        state = run_dir_state(run_dir)
        if state in ("complete", "complete-no-metrics"):
            record["action"] = "kept"
        else:
            from agrisim.episode import Episode

            output = {"empty": {}, "partial": {"overwrite": True}, "unfinished": {"resume": True}}[state]
            record["action"] = {"empty": "run", "partial": "run", "unfinished": "resume"}[state]
            _, summary = Episode(build_config(config, {"output": output})).run()
            if summary.status != "complete":
                raise RuntimeError(f"the run ended {summary.status}: {summary.error}")
        record["after"] = {name: _follow_up(run_dir, name, colmap) for name in after}
        failed = [f"{n}: {v}" for n, v in record["after"].items() if v not in ("done", "kept")]
        record.update(status="failed" if failed else "complete", error="; ".join(failed))
    except UserError as exc:
        record.update(status="failed", error=str(exc))
    except Exception as exc:  # an internal failure of this run; the others go on
        record.update(status="failed", error=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc())
    record["finished"] = time.time()
    record["seconds"] = round(time.perf_counter() - t0, 3)
    return record


def _follow_up(run_dir: Path, name: str, colmap: Mapping[str, Any]) -> str:
    """Follow-up ``name`` on the complete run: ``kept`` when done before, ``done``, or why not."""
    if follow_up_done(run_dir, name):
        return "kept"
    try:
        if name in ("coco", "nerfstudio"):  # agrisim export NAME, through the installed exporter
            from agrisim.files.exports import build_exporter, run_export
            from agrisim.registry import Registry, make_plugin_manager

            spec, exporter = build_exporter(Registry(make_plugin_manager()), name)
            run_export(spec, exporter, run_dir, overwrite=True)  # (a half-made one of a lost worker is replaced)
        else:
            from agrisim.plugins.poses.colmap.photogrammetry import run_colmap

            run_colmap(run_dir, overwrite=True, **colmap)
    except Exception as exc:  # one follow-up failing leaves the run and the others standing
        return f"failed: {type(exc).__name__}: {exc}"
    return "done"


# ---------------------------------------------------------------------------------- placement


def check_gpus(plan: SweepPlan, cluster: Mapping[str, float], gpus: int | None, resource: str) -> list[bool]:
    """Which cells take a GPU on this cluster; a UserError where more GPUs are asked for than
    it has, or a run needs one and it has none."""
    have = int(cluster.get(resource, 0))
    if gpus is not None and gpus > have:
        raise UserError(f"--gpus {gpus}: the Ray cluster has {have} {resource} resource{'s' * (have != 1)}")
    needs = [c.name for c in plan.cells if c.device == "gpu"]
    if needs and gpus == 0:
        raise UserError(f"--gpus 0: sweep cell {needs[0]} renders on a GPU")
    if needs and have == 0:
        raise UserError(
            f"sweep cell {needs[0]} renders on a GPU but the Ray cluster has no {resource} resource "
            "(set the renderer's variant to llvm or auto, or [sweep] gpu = false)"
        )
    return [c.device == "gpu" or (c.device == "auto" and have > 0 and gpus != 0) for c in plan.cells]


# ---------------------------------------------------------------------------------- the manifest


def cell_figures(cell: Cell) -> dict[str, Any]:
    """What a cell's folder holds: its run's status, views, the run's metrics summary (where
    there is one) and the follow-ups done, read from disk."""
    state = run_dir_state(cell.run_dir)
    figures: dict[str, Any] = {"state": state, "views": 0, "metrics": None}
    if state in ("complete", "complete-no-metrics", "unfinished"):
        from agrisim.files.rundir import read_json

        doc = read_json(cell.run_dir / layout.RUN_JSON, "")
        figures["views"] = len(doc.get("frames_complete") or [])
        figures["metrics"] = (doc.get("summary") or {}).get("metrics")
        figures["run_seconds"] = round(sum(((doc.get("summary") or {}).get("wall_s") or {}).values()), 3)
    return figures


@dataclass
class SweepResult:
    """What :func:`sweep` did: a manifest record per cell (plan order) and Ray's figures."""

    plan: SweepPlan
    runs: list[dict[str, Any]]
    status: str
    wall_s: float
    ray: dict[str, Any] = field(default_factory=dict)

    @property
    def failed(self) -> list[dict[str, Any]]:
        """The runs that did not complete."""
        return [r for r in self.runs if r["status"] != "complete"]


def _record(
    cell: Cell, figures: Mapping[str, Any], task: Mapping[str, Any] | None, earlier: Mapping[str, Any] | None
) -> dict[str, Any]:
    """A cell's manifest record: the plan's, the folder's ``figures`` (:func:`cell_figures`),
    this sweep's task record (or, for a cell not run now, the earlier manifest's)."""
    rec: dict[str, Any] = {
        "name": cell.name,
        "run_dir": cell.name,
        "settings": cell.settings,
        "device": cell.device,
    }
    rec["views"] = figures["views"]
    rec["metrics"] = figures["metrics"]
    if task is not None:
        rec.update({k: v for k, v in task.items() if k not in rec})
    elif earlier is not None and cell.action == "skip":  # kept from the sweep that made it
        rec.update({k: v for k, v in earlier.items() if k not in rec and k not in ("status", "action")})
        rec["action"] = "skip"
    if "run_seconds" in figures:
        rec["run_seconds"] = figures["run_seconds"]
    complete = figures["state"] in ("complete", "complete-no-metrics")
    if task is not None and task.get("status") == "failed":
        rec["status"] = "failed"
    elif task is not None and task.get("status") == "cancelled":
        rec["status"] = "cancelled"
    elif complete and (task is not None or cell.action == "skip"):
        rec["status"] = "complete"
    else:
        rec["status"] = {"unfinished": "unfinished"}.get(figures["state"], "pending")
    return rec


def _earlier(out: Path) -> dict[str, dict[str, Any]]:
    """The records of the manifest a resumed sweep left, by cell name."""
    from agrisim.files.rundir import read_json

    path = out / MANIFEST
    if not path.is_file():
        return {}
    try:
        return {r["name"]: r for r in read_json(path, "").get("runs") or [] if isinstance(r, dict) and "name" in r}
    except (UserError, KeyError, TypeError):  # a damaged manifest is rebuilt from the folders
        return {}


# ---------------------------------------------------------------------------------- running


TaskFn = Callable[[Mapping[str, Any], Sequence[str], Mapping[str, Any]], dict[str, Any]]
Progress = Callable[[int, int, int, int], None]


# Long because Ray's submit/wait/interrupt loop shares its state (pending tasks, records,
# progress); split, that state would travel between functions.
def sweep(
    plan: SweepPlan,
    *,
    ray_address: str | None = None,
    workers: int | None = None,
    gpus: int | None = None,
    gpu_resource: str = "GPU",
    progress: Progress | None = None,
    task: TaskFn = run_cell_task,
) -> SweepResult:
    """Run a planned sweep: start (or join) Ray, check the GPUs asked for, prepare ``out``,
    run every cell not complete as a Ray task, and write ``sweep.json``.

    Bad input found here (an unreachable ``ray_address``, more ``gpus`` than the cluster has)
    is a UserError raised before anything is written. ``workers`` caps the CPU runs at a time
    (default: as many as the cluster's cores allow), ``gpus`` the GPU runs (default: one per
    GPU of the cluster). ``progress(runs_done, runs, views_done, views)`` hears of every run
    ended and, about once a second, of the views saved. ``task`` is the body of each Ray task
    (:func:`run_cell_task`; tests wrap it).
    """
    import ray

    if workers is not None and workers < 1:
        raise UserError(f"--workers must be 1 or more, got {workers}")
    if gpus is not None and gpus < 0:
        raise UserError(f"--gpus must be 0 or more, got {gpus}")
    t0 = time.perf_counter()
    todo = [c for c in plan.cells if c.action != "skip"]
    if ray_address not in (None, "auto", "local") and not ray_address.startswith("ray://"):
        probe(ray_address)  # even where this process has a Ray already (which would be used instead)
    info = start_ray(workers=None, address=ray_address) if todo else {}
    earlier = _earlier(plan.out) if plan.resume else {}
    try:
        on_gpu = check_gpus(plan, ray.cluster_resources(), gpus, gpu_resource) if todo else []
        prepare_out(plan.out, plan.overwrite)
    except BaseException:
        if info:
            stop_ray(info)
        raise
    report: dict[str, Any] = {
        "agrisim_sweep": 1,
        "status": "running",
        "started_at": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command": sys.argv,
        "ray_address": ray_address,
        "workers": workers,
        "gpus": gpus,
        "gpu_resource": gpu_resource,
        "plan": plan.to_json(),
    }
    tasks: dict[int, dict[str, Any]] = {}
    # a cell's folder no longer changes once its task ended (or it was skipped): read it once,
    # not at every task's end (a sweep of n cells would read n^2 run.json files)
    settled: dict[int, dict[str, Any]] = {}

    def figures(i: int, cell: Cell) -> dict[str, Any]:
        if i in settled:
            return settled[i]
        found = cell_figures(cell)
        if i in tasks or cell.action == "skip":
            settled[i] = found
        return found

    def write_manifest(status: str) -> list[dict[str, Any]]:
        runs = [_record(c, figures(i, c), tasks.get(i), earlier.get(c.name)) for i, c in enumerate(plan.cells)]
        for i, run in enumerate(runs):
            if on_gpu:  # where this sweep placed it (cells it skipped keep the earlier word)
                run["gpu"] = on_gpu[i]
        report.update(status=status, wall_s=round(time.perf_counter() - t0, 3), ray=info, runs=runs)
        report["done"] = sum(r["status"] == "complete" for r in runs)
        write_json(plan.out / MANIFEST, report)
        return runs

    write_manifest("running")
    status = "interrupted"
    try:
        if todo:
            _execute(plan, on_gpu, tasks, workers, gpus, gpu_resource, progress, task, write_manifest)
        elif progress is not None:
            views = sum(c.views for c in plan.cells)
            progress(len(plan.cells), len(plan.cells), views, views)
        status = "complete"
    finally:
        runs = write_manifest(status)
        if status == "complete" and any(r["status"] != "complete" for r in runs):
            runs = write_manifest("incomplete")
        if info:
            stop_ray(info)
    return SweepResult(plan, runs, report["status"], report["wall_s"], info)


def _execute(
    plan: SweepPlan,
    on_gpu: list[bool],
    tasks: dict[int, dict[str, Any]],
    workers: int | None,
    gpus: int | None,
    gpu_resource: str,
    progress: Progress | None,
    task: TaskFn,
    write_manifest: Callable[[str], Any],
) -> None:
    """Submit the cells not skipped, at most ``workers`` CPU runs and ``gpus`` GPU runs at once
    (Ray's resources bound both besides), and collect their records into ``tasks``."""
    import ray

    cells = plan.cells
    # a fresh worker per run (max_calls=1): a run's memory goes back to the system when it ends,
    # and nothing one run leaves in a process can change another's result
    remote = {
        gpu: ray.remote(max_calls=1, max_retries=MAX_RETRIES, **task_resources(gpu, gpu_resource))(task)
        for gpu in (False, True)
    }
    limit = {False: workers or len(cells), True: gpus or len(cells)}
    queue = [i for i, c in enumerate(cells) if c.action != "skip"]
    running: set[int] = set()  # the cells under way, whose views are polled
    views_total = sum(c.views for c in cells)
    finished_cells = len(cells) - len(queue)
    last_poll = 0.0
    # views saved per cell: read once for a cell that is not running, polled for one that is
    views = {i: cell_figures(c)["views"] for i, c in enumerate(cells)}

    def report_progress() -> None:
        if progress is not None:
            for i in running:
                views[i] = cell_figures(cells[i])["views"]
            progress(finished_cells, len(cells), min(sum(views.values()), views_total), views_total)

    report_progress()

    def submit(i: int) -> Any:
        running.add(i)
        return remote[on_gpu[i]].remote(cells[i].config, list(plan.spec.after), plan.spec.colmap)

    def finished(i: int, record: Any, error: BaseException | None) -> None:
        nonlocal finished_cells
        running.discard(i)
        # lost beyond its retries: recorded as failed (an exception of the run itself is recorded
        # by the task, never retried: it would fail the same way)
        tasks[i] = record if error is None else {"status": "failed", "error": first_line(error)}
        finished_cells += 1
        views[i] = cell_figures(cells[i])["views"]
        write_manifest("running")

    def cancelled(i: int) -> None:
        tasks[i] = {"status": "cancelled", "error": "interrupted"}

    def tick(any_finished: bool) -> None:
        nonlocal last_poll
        if any_finished or time.monotonic() - last_poll > 1.0:
            last_poll = time.monotonic()
            report_progress()

    run_batch(queue, submit, finished, limits=limit, slot=lambda i: on_gpu[i], cancelled=cancelled, tick=tick)


__all__ = ["MAX_RETRIES", "SweepResult", "check_gpus", "run_cell_task", "sweep", "task_resources"]
