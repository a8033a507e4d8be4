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


def assert_view_is_the_saved_one(view: dict, out: Path) -> None:
    """What a client saw of one view (its JSON from tests/e2e/ros*_client.py) against the run
    directory: the TF chain ``world`` -> ``r1/camera_optical_frame`` is the saved pose, the RGB
    and labels are the saved PNGs' pixels, K is cameras.json's."""
    import hashlib
    import json

    import numpy as np
    from PIL import Image

    frame = view["frame"]
    cameras = json.loads((out / "cameras.json").read_text())
    assert view["frame_id"] == "r1/camera_optical_frame"
    saved = np.asarray(cameras["frames"][frame]["world_T_camera"])
    assert np.allclose(view["world_T_optical"], saved, atol=1e-6), frame
    rgb = np.asarray(Image.open(out / "rgb" / f"{frame}.png").convert("RGB"))
    labels = np.asarray(Image.open(out / "labels" / f"{frame}.png"))
    assert view["rgb_sha256"] == hashlib.sha256(rgb.tobytes()).hexdigest(), frame
    assert view["labels_sha256"] == hashlib.sha256(labels.tobytes()).hexdigest(), frame
    assert np.allclose(view["K"], np.asarray(cameras["intrinsics"]["K"]).reshape(-1))
