"""``agrisim ros --ros 1`` against real ROS 1 clients on loopback: Debian's roscore, a rospy
client in Debian's own Python (tests/e2e/ros1_client.py) and ``rostopic``, all started and
stopped here. What they saw is checked against the run directory the session saved: the TF
chain at each view against cameras.json's pose, the images against the saved PNGs, the
intrinsics, the refusals; Ctrl-C ends the session with its run complete."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from live_server import assert_view_is_the_saved_one, live_server
from PIL import Image

HERE = Path(__file__).parent
DEBIAN_PYTHON = "/usr/bin/python3"
needs_ros = pytest.mark.skipif(
    shutil.which("roscore") is None
    or subprocess.run(
        [DEBIAN_PYTHON, "-c", "import rospy, std_srvs.srv, trajectory_msgs.msg"], capture_output=True
    ).returncode,
    reason="Debian's ROS 1 is not installed (make ros)",
)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(port: int) -> dict[str, str]:
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_HOSTNAME="127.0.0.1")
    env.pop("ROS_IP", None)
    return env


def _agrisim(*args: str) -> list[str]:
    return [sys.executable, "-c", "import sys; from agrisim.app.cli import main; sys.exit(main())", *args]


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # a CI shell's background job may ignore it


@pytest.fixture
def roscore(tmp_path):  # noqa: ANN001, ANN201
    port = _free_port()
    env = dict(_env(port), ROS_LOG_DIR=str(tmp_path / "roslog"), ROS_HOME=str(tmp_path / "roshome"))
    core = subprocess.Popen(
        ["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        preexec_fn=_default_sigint,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 30
        while subprocess.run(["rosnode", "list"], env=env, capture_output=True).returncode != 0:
            assert time.monotonic() < deadline, "roscore did not come up"
            time.sleep(0.3)
        yield env
    finally:
        core.send_signal(signal.SIGINT)
        try:
            core.wait(timeout=15)
        except subprocess.TimeoutExpired:
            core.kill()


@needs_ros
def test_a_ros1_client_drives_the_arm_and_gets_exact_views(roscore, tmp_path) -> None:
    out = tmp_path / "live"
    with live_server("1", out, roscore) as server:
        seen_path = tmp_path / "seen.json"
        client = subprocess.run(
            [DEBIAN_PYTHON, str(HERE / "ros1_client.py"), str(seen_path), "--views", "2"],
            env=roscore, capture_output=True, text=True, timeout=180,
        )  # fmt: skip
        assert client.returncode == 0, client.stderr[-2000:]
        info = subprocess.run(
            ["rostopic", "echo", "-n", "1", "/r1/camera/camera_info/K"], env=roscore, capture_output=True, text=True,
            timeout=30,
        )  # fmt: skip
    assert server.returncode == 0, server.output
    assert "stopped: " in server.output

    seen = json.loads(seen_path.read_text())
    run = json.loads((out / "run.json").read_text())
    cameras = json.loads((out / "cameras.json").read_text())
    assert run["summary"]["status"] == "complete"
    # the trajectory: followed to the commanded joint positions, taking its 1 s on the wall clock
    assert np.allclose(seen["reached_q"], seen["commanded_q"], atol=1e-9)
    assert 0.8 < seen["motion_wall_s"] < 1.5
    # the views: the first after the move belongs to it, the second is a setpoint of its own
    frames = [v["frame"] for v in seen["views"]]
    assert frames == ["r1_000", "r1_001"] and run["frames_complete"] == [*frames, "r1_002"]  # the last: still serving
    K = np.asarray(cameras["intrinsics"]["K"], float)
    for view in seen["views"]:
        frame = view["frame"]
        assert view["success"] and view["encodings"] == ["rgb8", "32FC1", "mono8"]
        # TF (composed by the client from /tf_static and /tf), pixels and K: the saved view's
        assert_view_is_the_saved_one(view, out)
        depth_mm = np.asarray(Image.open(out / "depth" / f"{frame}.png"), float)
        depth = np.asarray(view["depth"]).reshape(depth_mm.shape)
        hit = depth_mm > 0
        assert np.isinf(depth[~hit]).all()  # REP 117/118: no return is +Inf
        assert np.abs(depth[hit] * 1000 - depth_mm[hit]).max() <= 0.5  # the PNG rounds to whole mm
    # rostopic, the other client, reads the same intrinsics
    assert info.returncode == 0, info.stderr
    assert np.allclose(
        json.loads(info.stdout.split("---")[0].strip().replace("(", "[").replace(")", "]")), K.reshape(-1)
    )
    # bad input: refused on the topic, naming the problem; the session still serves
    refusals = seen["refusals"]
    assert refusals["beyond_limits"].startswith("refused:") and "beyond its limits" in refusals["beyond_limits"]
    assert "expected each of" in refusals["wrong_names"]
    assert "collides" in refusals["collision"]
    # MoveIt's action: control_msgs' own MD5 sums (1.5, ROS 1), a goal executed and succeeded, bad
    # goals aborted with control_msgs' codes
    assert seen["md5"] == {
        "FollowJointTrajectoryGoal": "69636787b6ecbde4d61d711979bc7ecb",
        "FollowJointTrajectoryActionGoal": "cff5c1d533bf2f82dd0138d57f4304bb",
    }
    action = seen["action"]
    SUCCEEDED, ABORTED = 3, 4  # actionlib_msgs/GoalStatus
    assert (action["move"]["state"], action["move"]["error_code"]) == (SUCCEEDED, 0)
    assert seen["after_action_pan"] == pytest.approx(seen["action_target_pan"], abs=1e-9)
    assert (action["beyond_limits"]["state"], action["beyond_limits"]["error_code"]) == (ABORTED, -1)
    assert "beyond its limits" in action["beyond_limits"]["error_string"]
    assert (action["wrong_names"]["state"], action["wrong_names"]["error_code"]) == (ABORTED, -2)
    assert seen["still_serving"]
    assert seen["joint_states_hz"] == pytest.approx(50, rel=0.2)


@needs_ros
def test_no_roscore_is_refused_before_anything_is_written(tmp_path) -> None:
    out = tmp_path / "live"
    result = subprocess.run(
        _agrisim("ros", "--ros", "1", "--renderer", "none", "--out", str(out)),
        env=_env(_free_port()), capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0 and "no ROS master at http://127.0.0.1:" in result.stderr
    assert not out.exists()
