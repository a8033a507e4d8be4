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
import time
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.plugins.ros.live import LiveSession

from . import BridgeOptions
from .bridge import IMAGE_TOPICS, RosBridge


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


class Ros2Bridge(RosBridge):
    """Serves a :class:`LiveSession` to ROS 2 clients through Cyclone DDS."""

    def __init__(self, session: LiveSession, options: BridgeOptions) -> None:
        super().__init__(session, options)
        self._participant: Any = None

    def command_topic(self, arm: str) -> str:
        return f"/{arm}/arm_controller/joint_trajectory"

    def describe(self) -> list[str]:
        return [f"ROS_DOMAIN_ID {domain_id()}:", *super().describe()]

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
        reply = message("std_srvs/srv/Trigger_Response", request_header=True)
        dp = self._participant = DomainParticipant(domain_id())

        def writer(name: str, data_type: Any, latched: bool = False) -> Any:
            return DataWriter(dp, Topic(dp, name, data_type, qos=qos(latched)), qos=qos(latched))

        def reader(name: str, data_type: Any) -> Any:
            return DataReader(dp, Topic(dp, name, data_type, qos=qos()), qos=qos())

        m = self.m
        self.pub_joints = writer("rt/joint_states", m["sensor_msgs/msg/JointState"])
        self.pub_tf = writer("rt/tf", m["tf2_msgs/msg/TFMessage"])
        self.pub_events = writer("rt/agrisim/events", m["std_msgs/msg/String"])
        self.pub_arm_joints = {a: writer(f"rt/{a}/joint_states", m["sensor_msgs/msg/JointState"]) for a in self.arms}
        self.pub_images = {
            a: {k: writer(f"rt/{a}/camera/{k}", m["sensor_msgs/msg/Image"], True) for k in IMAGE_TOPICS}
            for a in self.arms
        }
        self.pub_info = {
            a: writer(f"rt/{a}/camera/camera_info", m["sensor_msgs/msg/CameraInfo"], True) for a in self.arms
        }
        # kept: a latched sample lives as long as its writer
        self.pub_tf_static = writer("rt/tf_static", m["tf2_msgs/msg/TFMessage"], latched=True)
        self.pub_tf_static.write(self.static_transforms())
        self.readers: list[tuple[Any, Any]] = []
        for a in self.arms:
            replies = writer(f"rr/{a}/captureReply", reply)

            def on_trajectory(msg: Any, a: str = a) -> None:
                self.run_trajectory(
                    a,
                    msg.joint_names,
                    [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points],
                    [list(p.positions) for p in msg.points],
                    [list(p.velocities) for p in msg.points],
                )

            def on_capture(msg: Any, a: str = a, replies: Any = replies) -> None:
                success, text = self.take_view(a)
                replies.write(reply(client_id=msg.client_id, sequence=msg.sequence, success=success, message=text))

            self.readers.append(
                (reader(f"rt{self.command_topic(a)}", m["trajectory_msgs/msg/JointTrajectory"]), on_trajectory)
            )
            self.readers.append((reader(f"rq/{a}/captureRequest", request), on_capture))
        self.start_threads((self._listen, "commands"))

    def close(self) -> None:
        self.stop_threads()
        self._participant = None  # Cyclone deletes the participant and its entities with it

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
                        self.say(f"failed: {type(exc).__name__}: {exc}", "err")
            if not took:
                self._closed.wait(0.005)

    # ------------------------------------------------------------------ ROS 2's messages
    def now(self) -> Any:
        ns = time.time_ns()
        return self.m["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def send(self, publisher: Any, message: Any) -> None:
        publisher.write(message)

    def _header(self, frame: str, stamp: Any) -> Any:
        return self.m["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def joint_state(self, stamp: Any, names: list[str], q: list[float], qd: list[float]) -> Any:
        return self.m["sensor_msgs/msg/JointState"](
            header=self._header("", stamp), name=names, position=q, velocity=qd, effort=[]
        )

    def transform(self, parent: str, child: str, stamp: Any, xyz: list[float], quat: list[float]) -> Any:
        m = self.m
        (x, y, z), (qx, qy, qz, qw) = xyz, quat
        return m["geometry_msgs/msg/TransformStamped"](
            header=self._header(parent, stamp),
            child_frame_id=child,
            transform=m["geometry_msgs/msg/Transform"](
                translation=m["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
                rotation=m["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
            ),
        )

    def tf_message(self, transforms: list[Any]) -> Any:
        return self.m["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def image(self, frame: str, stamp: Any, height: int, width: int, encoding: str, step: int, data: bytes) -> Any:
        return self.m["sensor_msgs/msg/Image"](
            header=self._header(frame, stamp),
            height=height,
            width=width,
            encoding=encoding,
            is_bigendian=0,
            step=step,
            data=data,
        )

    def camera_info(
        self,
        frame: str,
        stamp: Any,
        height: int,
        width: int,
        K: np.ndarray,
        P: np.ndarray,
        lens: tuple[str, list[float]],
    ) -> Any:
        m = self.m
        return m["sensor_msgs/msg/CameraInfo"](
            header=self._header(frame, stamp),
            height=height,
            width=width,
            distortion_model=lens[0],
            d=list(lens[1]),
            k=K.reshape(-1).tolist(),
            r=np.eye(3).reshape(-1).tolist(),
            p=P.reshape(-1).tolist(),
            binning_x=0,
            binning_y=0,
            roi=m["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
        )

    def say(self, line: str, level: str) -> None:
        print(line, flush=True)  # the node's log, as rospy's loginfo prints it
        self.pub_events.write(self.m["std_msgs/msg/String"](data=line))
