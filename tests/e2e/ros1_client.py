"""A ROS 1 client of ``agrisim ros --ros 1``, in Debian's own Python with Debian's rospy (it
imports nothing of agrisim): it drives arm ``r1`` and writes what it saw as JSON.

    /usr/bin/python3 ros1_client.py OUT.json [--views N]
    /usr/bin/python3 ros1_client.py OUT.json --count-images SECONDS   (only counts every arm's views)

1. waits for ``/joint_states`` and measures its rate over 2 s;
2. sends a trajectory moving the first joint by 0.3 rad in 1 s; times the first
   ``/joint_states`` that shows motion (command-to-motion) and the end of the motion;
3. calls ``/r1/capture`` N times, timing call to ``image_raw`` (trigger-to-images), and keeps
   each view's images (digests), ``camera_info`` and the TF chain ``world`` ->
   ``r1/camera_optical_frame`` from ``/tf`` and ``/tf_static`` at that moment;
4. sends bad trajectories (joint beyond its limit, wrong joint names, a target in collision) and
   records the answers on ``/agrisim/events``; then a last view shows the session went on.
"""

from __future__ import annotations

import argparse
import array
import hashlib
import json
import threading
import time

import rospy
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

ARM = "r1"
OPTICAL = f"{ARM}/camera_optical_frame"


class Seen:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.joint_times: list[float] = []
        self.joints: list[tuple[float, list[str], list[float]]] = []
        self.tf: dict[str, tuple[str, list[list[float]]]] = {}
        self.images: list[tuple[float, Image]] = []
        self.depth: list[Image] = []
        self.labels: list[Image] = []
        self.info: list[CameraInfo] = []
        self.events: list[str] = []

    def on_joints(self, msg: JointState) -> None:
        with self.lock:
            self.joints.append((time.monotonic(), list(msg.name), list(msg.position)))

    def on_tf(self, msg: TFMessage) -> None:
        with self.lock:
            for t in msg.transforms:
                r, p = t.transform.rotation, t.transform.translation
                self.tf[t.child_frame_id] = (t.header.frame_id, matrix([r.x, r.y, r.z, r.w], [p.x, p.y, p.z]))

    def on_image(self, msg: Image) -> None:
        with self.lock:
            self.images.append((time.monotonic(), msg))


def matrix(quat: list[float], xyz: list[float]) -> list[list[float]]:
    """4x4 of a unit quaternion (x, y, z, w) and a translation (Debian's Python has no numpy)."""
    x, y, z, w = quat
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), xyz[0]],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), xyz[1]],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), xyz[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]


def matmul(a: list[list[float]], b: list[list[float]]) -> list[list[float]]:
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def chain(tf: dict[str, tuple[str, list[list[float]]]], frame: str) -> list[list[float]]:
    """world_T_frame, composed up the tree."""
    T = [[float(i == j) for j in range(4)] for i in range(4)]
    while frame != "world":
        parent, parent_T_frame = tf[frame]
        T = matmul(parent_T_frame, T)
        frame = parent
    return T


def arm_positions(seen: Seen) -> tuple[float, list[float]]:
    with seen.lock:
        t, names, q = seen.joints[-1]
    return t, [q[names.index(f"{ARM}/{j}")] for j in JOINTS]


JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]


def wait(condition, timeout: float = 30.0) -> None:  # noqa: ANN001
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise TimeoutError("timed out")
        time.sleep(0.002)


def trajectory(names: list[str], points: list[tuple[list[float], float]]) -> JointTrajectory:
    msg = JointTrajectory(joint_names=names)
    msg.points = [JointTrajectoryPoint(positions=q, time_from_start=rospy.Duration.from_sec(t)) for q, t in points]
    return msg


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--views", type=int, default=1)
    ap.add_argument("--count-images", type=float, metavar="SECONDS")
    args = ap.parse_args()
    rospy.init_node("agrisim_client", anonymous=True, disable_signals=True)
    if args.count_images:
        count_images(args.out, args.count_images)
        return
    seen = Seen()
    rospy.Subscriber("/joint_states", JointState, seen.on_joints, queue_size=100)
    rospy.Subscriber("/tf", TFMessage, seen.on_tf, queue_size=100)
    rospy.Subscriber("/tf_static", TFMessage, seen.on_tf, queue_size=10)
    rospy.Subscriber(f"/{ARM}/camera/image_raw", Image, seen.on_image, queue_size=10)
    rospy.Subscriber(f"/{ARM}/camera/depth", Image, seen.depth.append, queue_size=10)
    rospy.Subscriber(f"/{ARM}/camera/labels", Image, seen.labels.append, queue_size=10)
    rospy.Subscriber(f"/{ARM}/camera/camera_info", CameraInfo, seen.info.append, queue_size=10)
    rospy.Subscriber("/agrisim/events", String, lambda m: seen.events.append(m.data), queue_size=100)
    command = rospy.Publisher(f"/{ARM}/arm_controller/command", JointTrajectory, queue_size=10)
    rospy.wait_for_service(f"/{ARM}/capture", timeout=30)
    capture = rospy.ServiceProxy(f"/{ARM}/capture", Trigger)
    wait(lambda: seen.joints and OPTICAL in seen.tf and command.get_num_connections() > 0)
    out: dict = {}

    # 1. the joint states' rate
    n0, t0 = len(seen.joints), time.monotonic()
    time.sleep(2.0)
    out["joint_states_hz"] = (len(seen.joints) - n0) / (time.monotonic() - t0)

    # 2. a trajectory in, motion out
    _, q0 = arm_positions(seen)
    q1 = list(q0)
    q1[0] += 0.3
    n_before = len(seen.joints)
    sent = time.monotonic()
    command.publish(trajectory(JOINTS, [(q1, 1.0)]))

    def first_motion() -> float | None:
        with seen.lock:
            later = seen.joints[n_before:]
        return next((t for t, names, q in later if abs(q[names.index(f"{ARM}/{JOINTS[0]}")] - q0[0]) > 1e-4), None)

    wait(lambda: first_motion() is not None)
    moved = first_motion()
    out["command_to_motion_s"] = moved - sent
    wait(lambda: any(e.startswith("done: r1 trajectory") for e in seen.events))
    out["motion_wall_s"] = time.monotonic() - moved  # the answer comes when the replay ends
    time.sleep(0.1)  # a joint state after the end
    out["reached_q"] = arm_positions(seen)[1]
    out["commanded_q"] = q1

    # 3. views on the trigger
    out["views"] = []
    for _ in range(args.views):
        n = len(seen.images)
        called = time.monotonic()
        answer = capture()
        wait(lambda n=n: len(seen.images) > n)
        got, image = seen.images[n]
        wait(
            lambda stamp=image.header.stamp: (
                seen.depth and seen.labels and seen.info and seen.depth[-1].header.stamp == stamp
            )
        )
        with seen.lock:
            world_T_optical = chain(seen.tf, OPTICAL)
        info = seen.info[-1]
        out["views"].append(
            {
                "success": answer.success,
                "frame": answer.message,
                "trigger_to_image_s": got - called,
                "width": image.width,
                "height": image.height,
                "encodings": [image.encoding, seen.depth[-1].encoding, seen.labels[-1].encoding],
                "frame_id": image.header.frame_id,
                "rgb_sha256": hashlib.sha256(bytes(image.data)).hexdigest(),
                "labels_sha256": hashlib.sha256(bytes(seen.labels[-1].data)).hexdigest(),
                "depth": array.array("f", bytes(seen.depth[-1].data)).tolist(),  # little-endian, as this machine
                "K": list(info.K),
                "world_T_optical": world_T_optical,
            }
        )

    # 4. bad input: refused on the events topic, and the session goes on
    bad = {
        "beyond_limits": trajectory(JOINTS, [([q1[0] + 20.0, *q1[1:]], 1.0)]),
        "wrong_names": trajectory(["nope", *JOINTS[1:]], [(q1, 1.0)]),
        "collision": trajectory(JOINTS, [([q1[0], 0.5, 0.0, *q1[3:]], 3.0)]),
    }
    out["refusals"] = {}
    for name, msg in bad.items():
        n = len(seen.events)
        command.publish(msg)

        def answer(n: int = n) -> str | None:  # the views' own lines may still be arriving
            return next((e for e in seen.events[n:] if not e.startswith("done: r1 view")), None)

        wait(lambda: answer() is not None)
        out["refusals"][name] = answer()
    # 5. MoveIt's way in: the FollowJointTrajectory action, with control_msgs' MD5 sums
    import os
    import sys

    import actionlib

    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "plugins", "ros"))
    from control_actions import follow_joint_trajectory

    msgs = follow_joint_trajectory()
    action = actionlib.SimpleActionClient(
        f"/{ARM}/arm_controller/follow_joint_trajectory", msgs["FollowJointTrajectoryAction"]
    )
    if not action.wait_for_server(rospy.Duration(30)):
        raise TimeoutError("no FollowJointTrajectory action server")
    out["md5"] = {n: msgs[n]._md5sum for n in ("FollowJointTrajectoryGoal", "FollowJointTrajectoryActionGoal")}
    out["action"] = {}
    _, here = arm_positions(seen)
    goals = {
        "move": trajectory(JOINTS, [([here[0] - 0.2, *here[1:]], 0.5)]),
        "beyond_limits": trajectory(JOINTS, [([here[0] + 20.0, *here[1:]], 1.0)]),
        "wrong_names": trajectory(["nope", *JOINTS[1:]], [(here, 1.0)]),
    }
    for name, traj in goals.items():
        action.send_goal(msgs["FollowJointTrajectoryGoal"](trajectory=traj))
        action.wait_for_result(rospy.Duration(30))
        result = action.get_result()
        out["action"][name] = {
            "state": action.get_state(),
            "error_code": result.error_code,
            "error_string": result.error_string,
        }
        if name == "move":
            time.sleep(0.1)  # a joint state after the end
            out["after_action_pan"] = arm_positions(seen)[1][0]
    out["action_target_pan"] = here[0] - 0.2
    out["still_serving"] = capture().success
    out["events"] = seen.events
    rospy.signal_shutdown("done")
    with open(args.out, "w") as f:
        json.dump(out, f)


def count_images(out: str, seconds: float) -> None:
    """Every arm's ``image_raw`` arrivals over ``seconds``, from the first one on."""
    arrivals: list[float] = []
    for arm in ("r1", "r2"):
        rospy.Subscriber(f"/{arm}/camera/image_raw", Image, lambda m: arrivals.append(time.monotonic()), queue_size=10)
    wait(lambda: arrivals, timeout=300)
    time.sleep(seconds)
    first, last = arrivals[0], arrivals[-1]
    rate = (len(arrivals) - 1) / (last - first) if last > first else 0.0
    rospy.signal_shutdown("done")
    with open(out, "w") as f:
        json.dump({"images": len(arrivals), "span_s": last - first, "images_per_s": rate}, f)


if __name__ == "__main__":
    main()
