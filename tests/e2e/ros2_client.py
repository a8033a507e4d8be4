"""A ROS 2 client of ``agrisim ros --ros 2``: a Cyclone DDS participant of its own process, with
ROS 2's topic names, QoS and types, that drives arm ``r1`` and writes what it saw as JSON.

    python ros2_client.py OUT.json [VIEWS]

The same steps as ros1_client.py: the joint states' rate, a trajectory in and the motion out,
two views on the trigger (service ``/r1/capture`` as rmw_cyclonedds carries it: request and
reply topics, the client's id and a sequence number), the TF chain at each view, and refusals.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from agrisim.plugins.ros.ros2 import domain_id
from agrisim.plugins.ros.ros2_types import message

ARM = "r1"
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
VOLATILE = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile, Policy.History.KeepLast(10)
)
LATCHED = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.TransientLocal, Policy.History.KeepLast(1))  # fmt: skip


def matrix(r, p):  # noqa: ANN001, ANN201
    import numpy as np
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    T[:3, 3] = [p.x, p.y, p.z]
    return T


def main() -> None:
    import numpy as np

    out_path = sys.argv[1]
    views = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    dp = DomainParticipant(domain_id())

    def reader(name: str, ros_type: str, qos: Qos = VOLATILE, **kw) -> DataReader:  # noqa: ANN003
        return DataReader(dp, Topic(dp, name, message(ros_type, **kw), qos=qos), qos=qos)

    deep = Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)),
        Policy.Durability.Volatile,
        Policy.History.KeepLast(500),
    )
    joints = reader("rt/joint_states", "sensor_msgs/msg/JointState", deep)  # counted over 2 s unread
    tf = reader("rt/tf", "tf2_msgs/msg/TFMessage")
    tf_static = reader("rt/tf_static", "tf2_msgs/msg/TFMessage", LATCHED)
    images = reader(f"rt/{ARM}/camera/image_raw", "sensor_msgs/msg/Image")
    labels = reader(f"rt/{ARM}/camera/labels", "sensor_msgs/msg/Image")
    info = reader(f"rt/{ARM}/camera/camera_info", "sensor_msgs/msg/CameraInfo")
    events = reader("rt/agrisim/events", "std_msgs/msg/String")
    replies = reader(f"rr/{ARM}/captureReply", "std_srvs/srv/Trigger_Response", request_header=True)
    Traj = message("trajectory_msgs/msg/JointTrajectory")
    Point = message("trajectory_msgs/msg/JointTrajectoryPoint")
    Duration = message("builtin_interfaces/msg/Duration")
    Header = message("std_msgs/msg/Header")
    Time = message("builtin_interfaces/msg/Time")
    Request = message("std_srvs/srv/Trigger_Request", request_header=True)
    command = DataWriter(dp, Topic(dp, f"rt/{ARM}/arm_controller/joint_trajectory", Traj, qos=VOLATILE), qos=VOLATILE)
    request = DataWriter(dp, Topic(dp, f"rq/{ARM}/captureRequest", Request, qos=VOLATILE), qos=VOLATILE)

    seen_joints: list[tuple[float, list[str], list[float]]] = []
    frames: dict[str, tuple[str, np.ndarray]] = {}
    seen_images: list[tuple[float, object]] = []
    seen_events: list[str] = []

    def pump() -> None:
        now = time.monotonic()
        seen_joints.extend((now, list(m.name), list(m.position)) for m in joints.take(N=100))
        for m in tf_static.take(N=10) + tf.take(N=100):
            for t in m.transforms:
                frames[t.child_frame_id] = (t.header.frame_id, matrix(t.transform.rotation, t.transform.translation))
        seen_images.extend((now, m) for m in images.take(N=10))
        seen_events.extend(m.data for m in events.take(N=100))

    def wait(condition, timeout: float = 30.0) -> None:  # noqa: ANN001
        end = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > end:
                raise TimeoutError("timed out")
            pump()
            time.sleep(0.002)

    def pan() -> float:
        _, names, q = seen_joints[-1]
        return q[names.index(f"{ARM}/{JOINTS[0]}")]

    def chain(frame: str) -> np.ndarray:
        T = np.eye(4)
        while frame != "world":
            parent, parent_T = frames[frame]
            T, frame = parent_T @ T, parent
        return T

    def trajectory(names: list[str], q: list[float], seconds: float):  # noqa: ANN202
        return Traj(
            header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
            joint_names=names,
            points=[Point(positions=q, velocities=[], accelerations=[], effort=[],
                          time_from_start=Duration(sec=int(seconds), nanosec=int(seconds % 1 * 1e9)))],
        )  # fmt: skip

    wait(lambda: seen_joints and f"{ARM}/camera_optical_frame" in frames and command.get_matched_subscriptions())
    wait(lambda: request.get_matched_subscriptions() and replies.get_matched_publications())
    out: dict = {}
    pump()  # what had queued up is counted before the window, not in it
    n0, t0 = len(seen_joints), time.monotonic()
    time.sleep(2.0)
    pump()
    out["joint_states_hz"] = (len(seen_joints) - n0) / (time.monotonic() - t0)

    _, names, q = seen_joints[-1]
    q0 = [q[names.index(f"{ARM}/{j}")] for j in JOINTS]
    q1 = [q0[0] + 0.3, *q0[1:]]
    n = len(seen_joints)
    sent = time.monotonic()
    command.write(trajectory(JOINTS, q1, 1.0))
    wait(lambda: any(abs(q[names.index(f"{ARM}/{JOINTS[0]}")] - q0[0]) > 1e-4 for _, names, q in seen_joints[n:]))
    moved = next(t for t, names, q in seen_joints[n:] if abs(q[names.index(f"{ARM}/{JOINTS[0]}")] - q0[0]) > 1e-4)
    out["command_to_motion_s"] = moved - sent
    wait(lambda: any(e.startswith("done: r1 trajectory") for e in seen_events))
    done = time.monotonic()
    out["motion_wall_s"] = done - moved  # the answer comes when the replay ends
    wait(lambda: time.monotonic() - done > 0.1)  # a joint state after the end
    out["reached_pan"], out["commanded_pan"] = pan(), q1[0]

    out["views"] = []
    for sequence in range(1, views + 1):
        n = len(seen_images)
        called = time.monotonic()
        request.write(Request(client_id=0xA61, sequence=sequence, structure_needs_at_least_one_member=0))
        answer: list = []
        wait(lambda answer=answer: answer.extend(replies.take(N=1)) or answer)
        wait(lambda n=n: len(seen_images) > n)
        got, image = seen_images[n]
        label = labels.read(N=1)[0]
        out["views"].append(
            {
                "client_id": answer[0].client_id,
                "sequence": answer[0].sequence,
                "success": answer[0].success,
                "frame": answer[0].message,
                "trigger_to_image_s": got - called,
                "frame_id": image.header.frame_id,
                "encodings": [image.encoding, label.encoding],
                "rgb_sha256": hashlib.sha256(image.data).hexdigest(),
                "labels_sha256": hashlib.sha256(label.data).hexdigest(),
                "K": list(info.read(N=1)[0].k),
                "world_T_optical": chain(f"{ARM}/camera_optical_frame").tolist(),
            }
        )

    out["refusals"] = {}
    bad = {
        "beyond_limits": trajectory(JOINTS, [q1[0] + 20.0, *q1[1:]], 1.0),
        "wrong_names": trajectory(["nope", *JOINTS[1:]], q1, 1.0),
        "collision": trajectory(JOINTS, [q1[0], 0.5, 0.0, *q1[3:]], 3.0),
    }
    for name, msg in bad.items():
        n = len(seen_events)
        command.write(msg)

        def answer_line(n: int = n) -> str | None:
            return next((e for e in seen_events[n:] if not e.startswith("done: r1 view")), None)

        wait(lambda: answer_line() is not None)
        out["refusals"][name] = answer_line()
    with open(out_path, "w") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main()
