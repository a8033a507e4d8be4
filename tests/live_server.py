"""``agrisim ros`` as the ROS tests start it: a small coltsfoot cell (96x54, kinematic arms, no
reconstruction or recording), served until the test's block ends with Ctrl-C."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # a CI shell's background job may ignore it


@contextmanager
def live_server(
    ros: str, out: Path, env: dict[str, str], *extra: str, ready: str = "serving the cell"
) -> Iterator[subprocess.Popen[str]]:
    """The server (with ``extra`` flags), once it has printed a line starting with ``ready``;
    after the block it has been stopped with SIGINT, and ``server.output`` holds what it printed
    after that."""
    server = subprocess.Popen(
        [sys.executable, "-c", "import sys; from agrisim.app.cli import main; sys.exit(main())",
         "ros", "--ros", ros, "--plant", "coltsfoot", "--resolution", "96x54", "--physics", "kinematic",
         "--recon", "none", "--no-rrd", "--set", "renderer.raycast.shadow_samples=0", "--out", str(out), *extra],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, preexec_fn=_default_sigint,
    )  # fmt: skip
    try:
        assert server.stdout is not None
        for line in server.stdout:
            if line.startswith(ready):
                break
        else:
            pytest.fail(f"agrisim ros exited with {server.wait()} before serving")
        yield server
    finally:
        server.send_signal(signal.SIGINT)
        server.output, _ = server.communicate(timeout=60)  # type: ignore[attr-defined]
