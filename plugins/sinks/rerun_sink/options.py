"""The ``[sink.rerun]`` settings: where the recording goes and whether a viewer is spawned."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlparse

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
    connect: str | None = None
    """Also stream live to the Rerun viewer or server at this gRPC URL
    (``rerun+http://HOST:PORT/proxy``); ``--serve-web`` sets it to the web viewer it starts."""

    @model_validator(mode="after")
    def _exclusive(self) -> RerunOptions:
        if not self.save and self.path is not None:
            raise ValueError("--rrd and --no-rrd exclude each other (path given with save = false)")
        if self.connect is not None:
            url = urlparse(self.connect)
            if url.scheme not in ("rerun+http", "rerun+https") or not url.hostname or url.port is None:
                raise ValueError(
                    f"connect {self.connect!r} is not a Rerun gRPC URL such as rerun+http://127.0.0.1:9876/proxy"
                )
        return self

    def recording_path(self, out_dir: Path) -> Path:
        """Where the recording is saved: ``path`` or ``OUT/recording.rrd``."""
        return Path(self.path).expanduser() if self.path is not None else Path(out_dir) / layout.RECORDING
