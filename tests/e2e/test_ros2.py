"""``agrisim ros --ros 2`` against a separate Cyclone DDS participant (tests/e2e/ros2_client.py,
its own process) on loopback, with ROS 2's topic names, QoS and types; and the bytes the bridge
sends decoded by an independent ROS 2 CDR implementation (rosbags). No ROS 2 distribution is
installed here: what ``ros2 topic echo`` itself would do is not tested."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from live_server import assert_view_is_the_saved_one, live_server  # noqa: E402

from agrisim.plugins.ros.ros2_types import message, store  # noqa: E402

HERE = Path(__file__).parent
#: discovery on loopback only, unicast: a test machine's other interfaces and other tests stay out
LOOPBACK = (
    "<CycloneDDS><Domain id='any'><General><Interfaces><NetworkInterface address='127.0.0.1'/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>30</MaxAutoParticipantIndex><Peers><Peer address='127.0.0.1'/></Peers>"
    "</Discovery></Domain></CycloneDDS>"
)


def _env() -> dict[str, str]:
    return dict(os.environ, ROS_DOMAIN_ID=str(random.randint(100, 200)), CYCLONEDDS_URI=LOOPBACK)


def test_what_the_bridge_writes_is_ros2_cdr_as_rosbags_reads_it() -> None:
    """Cyclone's bytes of the generated types, decoded by rosbags and encoded again: the same."""
    s = store()
    m = {
        n: message(n)
        for n in ("std_msgs/msg/Header", "builtin_interfaces/msg/Time", "sensor_msgs/msg/RegionOfInterest")
    }
    header = m["std_msgs/msg/Header"](stamp=m["builtin_interfaces/msg/Time"](sec=7, nanosec=9), frame_id="r1/x")
    samples = {
        "sensor_msgs/msg/Image": dict(header=header, height=2, width=3, encoding="32FC1", is_bigendian=0, step=12,
                                      data=np.arange(6, dtype="<f4").tobytes()),
        "sensor_msgs/msg/CameraInfo": dict(header=header, height=2, width=3, distortion_model="plumb_bob",
                                           d=[0.0] * 5, k=[float(i) for i in range(9)], r=[1.0] * 9,
                                           p=[2.0] * 12, binning_x=0, binning_y=0,
                                           roi=m["sensor_msgs/msg/RegionOfInterest"](x_offset=1, y_offset=2, height=3,
                                                                                      width=4, do_rectify=True)),
        "sensor_msgs/msg/JointState": dict(header=header, name=["a", "b"], position=[0.5, -1.25], velocity=[],
                                           effort=[]),
        "std_msgs/msg/String": dict(data="refused: r1: ..."),
    }  # fmt: skip
    for name, fields in samples.items():
        ours = message(name)(**fields).serialize()
        decoded = s.deserialize_cdr(ours, name)
        assert bytes(s.serialize_cdr(decoded, name)) == ours, name
    image = s.deserialize_cdr(
        message("sensor_msgs/msg/Image")(**samples["sensor_msgs/msg/Image"]).serialize(), "sensor_msgs/msg/Image"
    )
    assert image.header.stamp.nanosec == 9 and image.encoding == "32FC1"
    assert np.array_equal(image.data.view("<f4"), np.arange(6))
    # a service reply: rmw_cyclonedds' 16-byte header (client id, sequence), then the message
    reply = message("std_srvs/srv/Trigger_Response", request_header=True)(
        client_id=5, sequence=3, success=True, message="r1_000"
    ).serialize()
    assert reply[4:20] == (5).to_bytes(8, "little") + (3).to_bytes(8, "little")
    body = s.deserialize_cdr(reply[:4] + reply[20:], "std_srvs/srv/Trigger_Response")
    assert body.success and body.message == "r1_000"


def test_a_ros2_participant_drives_the_arm_and_gets_exact_views(tmp_path) -> None:
    out, env = tmp_path / "live", _env()
    with live_server("2", out, env) as server:
        seen_path = tmp_path / "seen.json"
        client = subprocess.run(
            [sys.executable, str(HERE / "ros2_client.py"), str(seen_path)], env=env, capture_output=True, text=True,
            timeout=180,
        )  # fmt: skip
        assert client.returncode == 0, client.stderr[-2000:]
    assert server.returncode == 0, server.output
    seen = json.loads(seen_path.read_text())
    run = json.loads((out / "run.json").read_text())
    assert run["summary"]["status"] == "complete"
    assert seen["reached_pan"] == pytest.approx(seen["commanded_pan"], abs=1e-9)
    assert 0.8 < seen["motion_wall_s"] < 1.5
    assert seen["joint_states_hz"] == pytest.approx(50, rel=0.2)
    assert [v["frame"] for v in seen["views"]] == ["r1_000", "r1_001"] == run["frames_complete"]
    for sequence, view in enumerate(seen["views"], 1):
        assert view["success"] and (view["client_id"], view["sequence"]) == (0xA61, sequence)
        assert view["encodings"] == ["rgb8", "mono8"]
        assert_view_is_the_saved_one(view, out)
    refusals = seen["refusals"]
    assert "beyond its limits" in refusals["beyond_limits"] and refusals["beyond_limits"].startswith("refused:")
    assert "expected each of" in refusals["wrong_names"]
    assert "collides" in refusals["collision"]


def test_a_bad_ros_domain_id_is_refused_before_anything_is_written(tmp_path) -> None:
    out = tmp_path / "live"
    result = subprocess.run(
        [sys.executable, "-c", "import sys; from agrisim.app.cli import main; sys.exit(main())",
         "ros", "--ros", "2", "--renderer", "none", "--out", str(out)],
        env=dict(_env(), ROS_DOMAIN_ID="300"), capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode == 2 and "ROS_DOMAIN_ID='300'" in result.stderr
    assert result.stderr.strip().count("\n") == 0 and not out.exists()


@pytest.mark.parametrize(
    ("rig", "grid", "frames"),
    [("paper", "1x1", ["r1_000", "r2_000"]), ("turntable", "2x2", ["c1_000", "c1_001", "c2_000", "c2_001"])],
)
def test_routine_runs_the_rigs_setpoints_while_serving(tmp_path, rig: str, grid: str, frames: list[str]) -> None:
    """``--routine``: the setpoints run (unpaced here), then the session serves on until Ctrl-C;
    on the turntable each camera is served as its own robot, its joint the stage's angle."""
    out = tmp_path / "live"
    with live_server("2", out, _env(), "--rig", rig, "--routine", "--setpoints", grid, "--real-time-factor", "0",
                     ready="the routine is done") as server:  # fmt: skip
        pass
    assert server.returncode == 0, server.output
    run = json.loads((out / "run.json").read_text())
    assert run["summary"]["status"] == "complete" and run["frames_complete"] == frames
