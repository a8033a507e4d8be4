"""The ``ros2`` bridge: a live session over Cyclone DDS, the DDS that ROS 2 speaks by default,
with ROS 2's conventions so that ROS 2 tools see ordinary topics:

- topic names ``rt/<topic>``; a service ``/S`` as ``rq/SRequest`` and ``rr/SReply`` whose
  samples begin with rmw_cyclonedds' request header (the client's id and sequence number,
  repeated in the reply);
- types named ``pkg::msg::dds_::Name_``, laid out as rosbags' ROS 2 definitions
  (:mod:`agrisim.plugins.ros.ros2_types`), plain CDR;
- QoS as rclcpp's defaults: reliable, volatile, keep last 10; ``/tf_static`` and the camera
  topics transient local, keep last 1 (latched);
- the domain from ``ROS_DOMAIN_ID`` (0), Cyclone's configuration from ``CYCLONEDDS_URI``.

The topics are those of :mod:`agrisim.plugins.ros`, except that the trajectory comes in on
``/A/arm_controller/joint_trajectory`` (ros2_control's name). No ROS 2 node graph is announced
(``ros_discovery_info``): ``ros2 topic`` sees the topics, ``ros2 node list`` not the node.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Any

import numpy as np

from agrisim import hookimpl
from agrisim.errors import UserError
from agrisim.files.rosbag import rep118
from agrisim.interfaces import Bridge, Capture
from agrisim.live import LiveSession, Refused
from agrisim.records import Run
from agrisim.robot.tf_tree import ArmFrames, quaternions

from . import BridgeOptions


def preflight(config: Any, options: BridgeOptions) -> None:
    """Cyclone DDS importable, and a usable ``ROS_DOMAIN_ID``."""
    try:
        import cyclonedds.domain  # noqa: F401
    except ImportError as exc:
        raise UserError(f"ROS 2 needs Cyclone DDS's Python binding: pip install cyclonedds ({exc})") from None
    domain_id()


def domain_id() -> int:
    """``ROS_DOMAIN_ID`` (0 when unset), as ROS 2 reads it: 0 to 232."""
    text = os.environ.get("ROS_DOMAIN_ID", "").strip() or "0"
    if not text.isdigit() or int(text) > 232:
        raise UserError(f"ROS_DOMAIN_ID={text!r}: must be a whole number from 0 to 232")
    return int(text)


def qos(latched: bool = False) -> Any:
    """rclcpp's default QoS (reliable, volatile, keep last 10), or a latched topic's (transient
    local, keep last 1)."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.util import duration

    if latched:
        return Qos(
            Policy.Reliability.Reliable(duration(milliseconds=100)),
            Policy.Durability.TransientLocal,
            Policy.History.KeepLast(1),
        )
    return Qos(
        Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile, Policy.History.KeepLast(10)
    )


class Ros2Bridge(Bridge):
    """Serves a :class:`LiveSession` to ROS 2 clients through Cyclone DDS."""

    def __init__(self, session: LiveSession, options: BridgeOptions) -> None:
        self.session, self.options = session, options
        self.arms = [a.name for a in session.cell.arms]
        self.frames = {a.name: ArmFrames(a.name, session.kinematics[a.name], a.urdf) for a in session.cell.arms}
        self._closed = threading.Event()
        self._threads: list[threading.Thread] = []
        self._participant: Any = None

    # ------------------------------------------------------------------ set-up
    def start(self) -> None:
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        from .ros2_types import message

        self.m = {
            name: message(name)
            for name in (
                "builtin_interfaces/msg/Time", "std_msgs/msg/Header", "std_msgs/msg/String",
                "sensor_msgs/msg/JointState", "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo",
                "sensor_msgs/msg/RegionOfInterest", "tf2_msgs/msg/TFMessage", "geometry_msgs/msg/TransformStamped",
                "geometry_msgs/msg/Transform", "geometry_msgs/msg/Vector3", "geometry_msgs/msg/Quaternion",
                "trajectory_msgs/msg/JointTrajectory",
            )
        }  # fmt: skip
        request = message("std_srvs/srv/Trigger_Request", request_header=True)
        self.Reply = message("std_srvs/srv/Trigger_Response", request_header=True)
        dp = self._participant = DomainParticipant(domain_id())
        topics: dict[str, Any] = {}

        def writer(name: str, ros_type: str, latched: bool = False) -> Any:
            topic = topics.setdefault(name, Topic(dp, f"rt{name}", self.m[ros_type], qos=qos(latched)))
            return DataWriter(dp, topic, qos=qos(latched))

        self.pub_joints = writer("/joint_states", "sensor_msgs/msg/JointState")
        self.pub_tf = writer("/tf", "tf2_msgs/msg/TFMessage")
        self.pub_tf_static = writer("/tf_static", "tf2_msgs/msg/TFMessage", latched=True)
        self.pub_events = writer("/agrisim/events", "std_msgs/msg/String")
        self.pub_arm_joints = {a: writer(f"/{a}/joint_states", "sensor_msgs/msg/JointState") for a in self.arms}
        self.pub_images = {
            a: {k: writer(f"/{a}/camera/{k}", "sensor_msgs/msg/Image", True) for k in ("image_raw", "depth", "labels", "instances")}
            for a in self.arms
        }  # fmt: skip
        self.pub_info = {a: writer(f"/{a}/camera/camera_info", "sensor_msgs/msg/CameraInfo", True) for a in self.arms}
        self.readers: list[tuple[Any, Any]] = []
        self.replies: dict[str, Any] = {}
        for a in self.arms:
            t = Topic(
                dp, f"rt/{a}/arm_controller/joint_trajectory", self.m["trajectory_msgs/msg/JointTrajectory"], qos=qos()
            )
            self.readers.append((DataReader(dp, t, qos=qos()), lambda msg, a=a: self._on_trajectory(a, msg)))
            rq = Topic(dp, f"rq/{a}/captureRequest", request, qos=qos())
            rr = Topic(dp, f"rr/{a}/captureReply", self.Reply, qos=qos())
            self.replies[a] = DataWriter(dp, rr, qos=qos())
            self.readers.append((DataReader(dp, rq, qos=qos()), lambda msg, a=a: self._on_capture(a, msg)))
        self.pub_tf_static.write(self.m["tf2_msgs/msg/TFMessage"](transforms=self._static_transforms()))
        self.session.pm.register(self, name="bridge:ros2")
        for target, name in ((self._publish_state, "state"), (self._listen, "commands")):
            thread = threading.Thread(target=target, name=f"agrisim-ros2-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)

    def describe(self) -> list[str]:
        lines = [f"ROS_DOMAIN_ID {domain_id()}: /joint_states, /tf, /tf_static, /agrisim/events"]
        for a in self.arms:
            lines.append(
                f"/{a}/arm_controller/joint_trajectory (in), /{a}/capture (std_srvs/Trigger), /{a}/joint_states, "
                f"/{a}/camera/{{image_raw,depth,labels,instances,camera_info}}"
            )
        return lines

    def close(self) -> None:
        self._closed.set()
        for thread in self._threads:
            thread.join(timeout=5)
        self._threads = []
        if self.session.pm.is_registered(self):
            self.session.pm.unregister(self)
        self._participant = None  # Cyclone deletes the participant and its entities with it

    # ------------------------------------------------------------------ out
    def _stamp(self) -> Any:
        ns = time.time_ns()
        return self.m["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def _header(self, frame: str, stamp: Any) -> Any:
        return self.m["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def _transforms(self, edges: list[tuple[str, str]], T: np.ndarray, stamp: Any) -> list[Any]:
        m = self.m
        out = []
        for (parent, child), Ti, qi in zip(edges, T, quaternions(T), strict=True):
            x, y, z = (float(v) for v in Ti[:3, 3])
            qx, qy, qz, qw = (float(v) for v in qi)
            out.append(
                m["geometry_msgs/msg/TransformStamped"](
                    header=self._header(parent, stamp),
                    child_frame_id=child,
                    transform=m["geometry_msgs/msg/Transform"](
                        translation=m["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
                        rotation=m["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
                    ),
                )
            )
        return out

    def _static_transforms(self) -> list[Any]:
        stamp = self._stamp()
        out = []
        for a, frames in self.frames.items():
            edges, T = frames.static(np.asarray(self.session.cell.arm(a).home, float))
            out += self._transforms(edges, T, stamp)
        return out

    def _joint_state(self, stamp: Any, names: list[str], q: list[float], qd: list[float]) -> Any:
        return self.m["sensor_msgs/msg/JointState"](
            header=self._header("", stamp), name=names, position=q, velocity=qd, effort=[]
        )

    def _publish_state(self) -> None:
        """/joint_states and /tf at the rate, from where the arms are on the wall clock."""
        period = 1.0 / self.options.rate
        tick = time.monotonic()
        while not self._closed.is_set():
            state = self.session.motion.state()
            stamp = self._stamp()
            names, q_all, qd_all, transforms = [], [], [], []
            for a in self.arms:
                q, qd = state[a]
                joints = self.session.joint_names(a)
                velocity = [] if np.isnan(qd).any() else [float(v) for v in qd]
                self.pub_arm_joints[a].write(self._joint_state(stamp, joints, [float(v) for v in q], velocity))
                names += [f"{a}/{j}" for j in joints]
                q_all += [float(v) for v in q]
                qd_all += velocity if velocity else [0.0] * len(q)
                transforms += self._transforms(self.frames[a].moving_edges, self.frames[a].moving(q), stamp)
            self.pub_joints.write(self._joint_state(stamp, names, q_all, qd_all))
            self.pub_tf.write(self.m["tf2_msgs/msg/TFMessage"](transforms=transforms))
            tick += period
            self._closed.wait(max(0.0, tick - time.monotonic()))
            tick = max(tick, time.monotonic() - period)

    def _image(self, frame: str, stamp: Any, pixels: np.ndarray, encoding: str) -> Any:
        pixels = np.ascontiguousarray(pixels)
        if pixels.dtype.byteorder == ">":
            pixels = pixels.astype(pixels.dtype.newbyteorder("<"))
        return self.m["sensor_msgs/msg/Image"](
            header=self._header(frame, stamp),
            height=pixels.shape[0],
            width=pixels.shape[1],
            encoding=encoding,
            is_bigendian=0,
            step=int(pixels.strides[0]),
            data=pixels.tobytes(),
        )

    @hookimpl
    def agrisim_capture(self, run: Run, capture: Capture) -> None:
        images = capture.images
        if images is None or capture.robot not in self.pub_images:
            return
        stamp = self._stamp()
        frame = f"{capture.robot}/camera_optical_frame"
        K = np.asarray(capture.camera.K, float)
        P = np.zeros((3, 4))
        P[:, :3] = K
        self.pub_info[capture.robot].write(
            self.m["sensor_msgs/msg/CameraInfo"](
                header=self._header(frame, stamp),
                height=int(images.rgb.shape[0]),
                width=int(images.rgb.shape[1]),
                distortion_model="plumb_bob",
                d=[0.0] * 5,
                k=K.reshape(-1).tolist(),
                r=np.eye(3).reshape(-1).tolist(),
                p=P.reshape(-1).tolist(),
                binning_x=0,
                binning_y=0,
                roi=self.m["sensor_msgs/msg/RegionOfInterest"](
                    x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
                ),
            )
        )
        pub = self.pub_images[capture.robot]
        pub["depth"].write(self._image(frame, stamp, rep118(images.depth), "32FC1"))
        pub["labels"].write(self._image(frame, stamp, images.labels.astype(np.uint8), "mono8"))
        if images.instances is not None:
            pub["instances"].write(self._image(frame, stamp, images.instances.astype(np.uint16), "mono16"))
        pub["image_raw"].write(self._image(frame, stamp, images.rgb, "rgb8"))

    def _event(self, line: str) -> None:
        print(line, flush=True)
        self.pub_events.write(self.m["std_msgs/msg/String"](data=line))

    # ------------------------------------------------------------------ in
    def _listen(self) -> None:
        """Take what the readers hold and act on it, one command at a time, in arrival order."""
        while not self._closed.is_set():
            took = False
            for reader, act in self.readers:
                for sample in reader.take(N=16):
                    took = True
                    if not sample.sample_info.valid_data:  # a writer gone (its instance unregistered)
                        continue
                    try:
                        act(sample)
                    except Exception as exc:  # a bridge bug must not end the session
                        self._event(f"failed: {type(exc).__name__}: {exc}")
            if not took:
                self._closed.wait(0.005)

    def _on_trajectory(self, arm: str, msg: Any) -> None:
        names = [n.removeprefix(f"{arm}/") for n in msg.joint_names]
        times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points]
        positions = [list(p.positions) for p in msg.points]
        velocities = [list(p.velocities) for p in msg.points]
        s = self.session
        try:
            result = s.submit(lambda: s.execute(arm, names, times, positions, velocities)).result()
        except Refused as exc:
            self._event(f"refused: {exc}")
            return
        except Exception as exc:
            self._event(f"failed: {arm} trajectory: {type(exc).__name__}: {exc}")
            return
        outcome = "reached" if result.reached else f"not reached: {result.reason}"
        self._event(f"done: {arm} trajectory {result.frame} ({result.duration_s:.3f} s simulated), {outcome}")

    def _on_capture(self, arm: str, request: Any) -> None:
        s = self.session

        def reply(success: bool, message: str) -> None:
            self.replies[arm].write(
                self.Reply(client_id=request.client_id, sequence=request.sequence, success=success, message=message)
            )

        try:
            capture = s.submit(lambda: s.capture(arm)).result()
        except Refused as exc:
            self._event(f"refused: {exc}")
            reply(False, str(exc))
            return
        except Exception as exc:
            self._event(f"failed: {arm} capture: {type(exc).__name__}: {exc}")
            reply(False, f"{type(exc).__name__}: {exc}")
            return
        self._event(f"done: {arm} view {capture.frame}")
        reply(True, capture.frame)
