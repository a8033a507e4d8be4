"""Runs a batch of items as Ray tasks, the loop ``agrisim compare`` and ``agrisim sweep`` share:
at most so many tasks of each class at once (CPU runs, GPU runs), each result handed on as it
comes, Ray's own errors (a worker or node lost beyond its retries) handed on as failures, and on
Ctrl-C every task still running cancelled and handed on as such."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Hashable, Mapping
from typing import Any, TypeVar

T = TypeVar("T")


def run_batch(
    queue: list[T],
    submit: Callable[[T], Any],
    finished: Callable[[T, Any, BaseException | None], None],
    *,
    limits: Mapping[Any, int],
    slot: Callable[[T], Hashable] = lambda item: None,
    cancelled: Callable[[T], None] = lambda item: None,
    tick: Callable[[bool], None] | None = None,
    tick_s: float = 1.0,
) -> None:
    """Submit ``queue``'s items in order (``submit(item)`` returns the task's object ref), never
    more of a ``slot(item)`` class at once than ``limits`` says, and call ``finished(item,
    value, error)`` as each task ends: ``error`` is the ``RayError`` of a task Ray lost, else
    None. ``tick(any_finished)``, when given, is called at least every ``tick_s`` seconds
    (progress that tasks report on their own). On KeyboardInterrupt every running task is
    cancelled and handed to ``cancelled``; the interrupt goes on."""
    import ray

    pending: dict[Any, T] = {}
    running: Counter[Hashable] = Counter()
    try:
        while queue or pending:
            for item in list(queue):
                if running[slot(item)] < limits[slot(item)]:
                    queue.remove(item)
                    running[slot(item)] += 1
                    pending[submit(item)] = item
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=tick_s if tick is not None else None)
            for ref in ready:
                item = pending.pop(ref)
                running[slot(item)] -= 1
                try:
                    value, error = ray.get(ref), None
                except ray.exceptions.RayError as exc:  # the worker died (OOM killer, segfault, a lost node)
                    value, error = None, exc
                finished(item, value, error)
            if tick is not None:
                tick(bool(ready))
    except KeyboardInterrupt:
        for ref, item in pending.items():
            ray.cancel(ref, force=True)
            cancelled(item)
        raise


def first_line(error: BaseException) -> str:
    """``Type: first line`` of a Ray error, for a run's record."""
    return f"{type(error).__name__}: {(str(error).strip().splitlines() or [''])[0]}"


__all__ = ["first_line", "run_batch"]
