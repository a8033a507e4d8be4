"""Progress bars for long work (episodes, re-renders, sweeps), on stderr, quiet when stderr is
not a terminal."""

from __future__ import annotations

import sys
from types import TracebackType
from typing import TypeVar

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

_B = TypeVar("_B", bound="_Bar")


class _Bar:
    """A rich bar of ``columns`` on stderr, shown while the ``with`` block runs."""

    def __init__(self, *columns: ProgressColumn | str) -> None:
        self._console = Console(file=sys.stderr)
        self._progress = Progress(
            *columns, console=self._console, transient=True, disable=not self._console.is_terminal
        )

    def __enter__(self: _B) -> _B:
        self._progress.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._progress.stop()


class EpisodeProgress(_Bar):
    """``with EpisodeProgress() as p: episode.run(progress=p.update)``."""

    def __init__(self, description: str = "setpoints") -> None:
        super().__init__(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
        )
        self._task = self._progress.add_task(description, total=None)

    def update(self, done: int, total: int) -> None:
        self._progress.update(self._task, completed=done, total=total)

    def stage(self, name: str, done: int, total: int) -> None:
        """``update``, the bar then named ``name`` (work in stages, each counted apart)."""
        self._progress.update(self._task, description=name, completed=done, total=total)


class SweepProgress(_Bar):
    """``agrisim sweep``'s bar: views saved out of those planned (the ETA comes from their
    rate), runs done, views per second since the sweep started."""

    def __init__(self) -> None:
        from rich.progress import TaskProgressColumn

        super().__init__(
            TextColumn("[bold]runs {task.fields[runs]}"),
            BarColumn(),
            TextColumn("views {task.completed:.0f}/{task.total:.0f}"),
            TaskProgressColumn(),
            TextColumn("{task.fields[rate]}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
        )
        self._task = self._progress.add_task("sweep", total=None, runs="0/?", rate="")
        self._start: tuple[float, int] | None = None

    def update(self, runs_done: int, runs: int, views_done: int, views: int) -> None:
        """``runs_done`` of ``runs`` ended, ``views_done`` of ``views`` saved."""
        import time

        now = time.monotonic()
        if self._start is None:  # views kept from before a --resume do not count in the rate
            self._start = (now, views_done)
        seconds = now - self._start[0]
        rate = f"{(views_done - self._start[1]) / seconds:.2f} views/s" if seconds > 1 else ""
        self._progress.update(
            self._task, completed=views_done, total=max(views, 1), runs=f"{runs_done}/{runs}", rate=rate
        )
