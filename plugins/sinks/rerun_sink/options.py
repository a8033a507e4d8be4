"""The ``[sink.rerun]`` settings: where the recording goes and whether a viewer is spawned."""

from __future__ import annotations

from pathlib import Path

from pydantic import model_validator

from agrisim import Options
from agrisim.files import layout


class RerunOptions(Options):
    """Options of the ``rerun`` sink (``[sink.rerun]``)."""

    path: Path | None = None
    """Recording file (``--rrd``); default: OUT/recording.rrd."""
    save: bool = True
    """Write the recording to a file (``--no-rrd``: false)."""
    spawn: bool = False
    """Also stream to a Rerun viewer spawned for the run (``--spawn``)."""

    @model_validator(mode="after")
    def _exclusive(self) -> RerunOptions:
        if not self.save and self.path is not None:
            raise ValueError("--rrd and --no-rrd exclude each other (path given with save = false)")
        return self

    def recording_path(self, out_dir: Path) -> Path:
        """Where the recording is saved: ``path`` or ``OUT/recording.rrd``."""
        return Path(self.path).expanduser() if self.path is not None else Path(out_dir) / layout.RECORDING
