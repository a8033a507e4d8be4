"""Live ROS figures of ``agrisim ros`` (issue 33): command-to-motion latency,
trigger-to-images latency, the ``/joint_states`` rate, and the images' rate under ``--routine``.
Prints figures; asserts nothing.

Everything on loopback: for ROS 1 a roscore on a free port, agrisim's node, and the rospy client
of the tests (``tests/e2e/ros1_client.py``, in Debian's own Python; needs ``make ros``); for
ROS 2 agrisim's Cyclone DDS participant and the tests' DDS client (``tests/e2e/ros2_client.py``).

    python bench/ros_live.py [--ros 1|2] [--resolution 960x540] [--views 10] [--physics pybullet]

Command-to-motion is from the client's publish to the first ``/joint_states`` showing the arm
moving; the physics computes the whole trajectory before it is replayed on the wall clock, so
this includes that computation. Trigger-to-images is from the service call to ``image_raw``
arriving (the view is rendered, published, and queued for saving before the call returns).
"""

from __future__ import annotations

import argparse
import json
import platform
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CLIENT = REPO / "tests" / "e2e" / "ros1_client.py"
CLIENT2 = REPO / "tests" / "e2e" / "ros2_client.py"
LOOPBACK = (
    "<CycloneDDS><Domain id='any'><General><Interfaces><NetworkInterface address='127.0.0.1'/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>30</MaxAutoParticipantIndex><Peers><Peer address='127.0.0.1'/></Peers>"
    "</Discovery></Domain></CycloneDDS>"
)


def cpu_model() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def serve(env: dict, out: Path, args: argparse.Namespace, *extra: str) -> subprocess.Popen:
    cmd = [sys.executable, "-c", "import sys; from agrisim.app.cli import main; sys.exit(main())", "ros", "--ros", args.ros,
           "--plant", args.plant, "--resolution", args.resolution, "--physics", args.physics, "--recon", "none",
           "--no-rrd", "--out", str(out), *extra]  # fmt: skip
    server = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert server.stdout is not None
    for line in server.stdout:
        if line.startswith("serving the cell"):
            return server
    raise SystemExit(f"agrisim ros exited with {server.wait()} before serving")


def stop(server: subprocess.Popen) -> None:
    server.send_signal(signal.SIGINT)
    server.communicate(timeout=120)


def report(seen: dict) -> None:
    lat = np.array([v["trigger_to_image_s"] for v in seen["views"]]) * 1e3
    print(f"/joint_states: {seen['joint_states_hz']:.1f} Hz (the default rate, 50 Hz)")
    print(f"command to motion: {seen['command_to_motion_s'] * 1e3:.0f} ms (a 1 s, 0.3 rad move; "
          f"replayed in {seen['motion_wall_s']:.3f} s)")  # fmt: skip
    print(f"trigger to images: median {np.median(lat):.0f} ms, min {lat.min():.0f}, max {lat.max():.0f} "
          f"({len(lat)} views)")  # fmt: skip


def ros2(args: argparse.Namespace, tmp: Path, env: dict) -> None:
    print(f"CPU: {cpu_model()}; ROS 2 (Cyclone DDS, loopback); {args.resolution}, raycast defaults, "
          f"{args.physics} physics, {args.plant}")  # fmt: skip
    server = serve(env, tmp / "commands", args)
    try:
        seen_path = tmp / "seen.json"
        subprocess.run([sys.executable, str(CLIENT2), str(seen_path), str(args.views)], env=env, check=True,
                       timeout=600)  # fmt: skip
    finally:
        stop(server)
    report(json.loads(seen_path.read_text()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ros", choices=["1", "2"], default="1")
    ap.add_argument("--resolution", default="960x540")
    ap.add_argument("--views", type=int, default=10)
    ap.add_argument("--physics", default="pybullet")
    ap.add_argument("--plant", default="coltsfoot")
    ap.add_argument("--routine-setpoints", default="2x5")
    ap.add_argument("--routine-seconds", type=float, default=60.0)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="agrisim-ros-bench-"))
    import os

    if args.ros == "2":
        ros2(args, tmp, dict(os.environ, ROS_DOMAIN_ID="77", CYCLONEDDS_URI=LOOPBACK))
        return
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_HOSTNAME="127.0.0.1",
               ROS_LOG_DIR=str(tmp / "roslog"), ROS_HOME=str(tmp / "roshome"))  # fmt: skip
    core = subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        while subprocess.run(["rosnode", "list"], env=env, capture_output=True).returncode:
            time.sleep(0.3)
        print(f"CPU: {cpu_model()}; ROS 1; {args.resolution}, raycast defaults, {args.physics} physics, {args.plant}")

        server = serve(env, tmp / "commands", args)
        try:
            seen_path = tmp / "seen.json"
            subprocess.run(["/usr/bin/python3", str(CLIENT), str(seen_path), "--views", str(args.views)], env=env,
                           check=True, timeout=600)  # fmt: skip
        finally:
            stop(server)
        report(json.loads(seen_path.read_text()))

        for rtf in ("1", "0"):
            counted = tmp / f"routine-{rtf}.json"
            counter = subprocess.Popen(["/usr/bin/python3", str(CLIENT), str(counted), "--count-images",
                                        str(args.routine_seconds)], env=env)  # fmt: skip
            time.sleep(2.0)  # subscribed before the first view
            server = serve(env, tmp / f"routine-{rtf}", args, "--routine", "--setpoints", args.routine_setpoints,
                           "--real-time-factor", rtf)  # fmt: skip
            try:
                counter.wait(timeout=args.routine_seconds + 400)
            finally:
                stop(server)
            c = json.loads(counted.read_text())
            pace = "paced at real time" if rtf == "1" else "unpaced (--real-time-factor 0)"
            print(f"--routine, {pace}: {c['images_per_s']:.2f} views/s on image_raw "
                  f"({c['images']} views over {c['span_s']:.1f} s, both arms)")  # fmt: skip
    finally:
        core.send_signal(signal.SIGINT)
        core.wait(timeout=30)


if __name__ == "__main__":
    main()
