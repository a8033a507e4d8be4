"""The ``ros1`` bridge: a live session as a rospy node named ``agrisim`` (topics and services in
:mod:`agrisim.plugins.ros`). rospy runs subscriber callbacks and service handlers on threads of
its own; they queue work for the session's thread and wait for its answer, so a trigger returns
once its view is rendered, published and saved."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from agrisim.errors import UserError
from agrisim.plugins.ros.live import LiveSession

from . import BridgeOptions
from .bridge import IMAGE_TOPICS, RosBridge
from .rospy_env import import_rospy

if TYPE_CHECKING:
    from types import ModuleType


def preflight(config: Any, options: BridgeOptions) -> None:
    """rospy importable and a ROS master answering, before anything is written."""
    import_rospy()
    import rosgraph

    if not rosgraph.is_master_online():
        raise UserError(f"no ROS master at {rosgraph.get_master_uri()}: start roscore, or set ROS_MASTER_URI")


class Ros1Bridge(RosBridge):
    """Serves a :class:`LiveSession` to ROS 1 clients."""

    def __init__(self, session: LiveSession, options: BridgeOptions) -> None:
        super().__init__(session, options)
        self._started = False

    def command_topic(self, arm: str) -> str:
        return f"/{arm}/arm_controller/command"

    def start(self) -> None:
        rospy = import_rospy()
        from sensor_msgs.msg import CameraInfo, Image, JointState
        from std_msgs.msg import String
        from std_srvs.srv import Trigger, TriggerResponse
        from tf2_msgs.msg import TFMessage
        from trajectory_msgs.msg import JointTrajectory

        self.rospy: ModuleType = rospy
        # agrisim handles Ctrl-C itself: the session must close and save the run
        rospy.init_node("agrisim", disable_signals=True)
        self._started = True
        P = rospy.Publisher
        self.pub_joints = P("/joint_states", JointState, queue_size=10)
        self.pub_tf = P("/tf", TFMessage, queue_size=100)
        self.pub_events = P("/agrisim/events", String, queue_size=100)
        self.pub_arm_joints = {a: P(f"/{a}/joint_states", JointState, queue_size=10) for a in self.arms}
        self.pub_images = {
            a: {kind: P(f"/{a}/camera/{kind}", Image, queue_size=2, latch=True) for kind in IMAGE_TOPICS}
            for a in self.arms
        }
        self.pub_info = {a: P(f"/{a}/camera/camera_info", CameraInfo, queue_size=2, latch=True) for a in self.arms}
        self.pub_tf_static = P("/tf_static", TFMessage, queue_size=1, latch=True)  # latched: kept
        self.pub_tf_static.publish(self.static_transforms())

        def on_trajectory(msg: Any, arm: str) -> None:
            self.run_trajectory(
                arm,
                msg.joint_names,
                [p.time_from_start.to_sec() for p in msg.points],
                [list(p.positions) for p in msg.points],
                [list(p.velocities) for p in msg.points],
            )

        self._subs = [
            rospy.Subscriber(self.command_topic(a), JointTrajectory, on_trajectory, callback_args=a, queue_size=10)
            for a in self.arms
        ]
        self._services = [
            rospy.Service(f"/{a}/capture", Trigger, lambda req, a=a: TriggerResponse(*self.take_view(a)))
            for a in self.arms
        ]
        self._actions = [self._follow_joint_trajectory(a) for a in self.arms]
        self.start_threads()

    def _follow_joint_trajectory(self, arm: str) -> Any:
        """``/A/arm_controller/follow_joint_trajectory``, the action MoveIt's controller
        manager sends trajectories through: each goal executed whole, then succeeded or aborted
        with control_msgs' error code and the reason."""
        import actionlib

        from .control_actions import follow_joint_trajectory

        msgs = follow_joint_trajectory()
        Result = msgs["FollowJointTrajectoryResult"]
        codes = {
            "reached": Result.SUCCESSFUL,
            "refused:joints": Result.INVALID_JOINTS,
            "refused:goal": Result.INVALID_GOAL,
            "not reached": Result.GOAL_TOLERANCE_VIOLATED,
            "failed": Result.INVALID_GOAL,
        }

        def execute(goal: Any) -> None:
            t = goal.trajectory
            outcome, line = self.run_trajectory(
                arm,
                t.joint_names,
                [p.time_from_start.to_sec() for p in t.points],
                [list(p.positions) for p in t.points],
                [list(p.velocities) for p in t.points],
            )
            result = Result(error_code=codes[outcome], error_string="" if outcome == "reached" else line)
            if outcome == "reached":
                server.set_succeeded(result)
            else:
                server.set_aborted(result, line)

        server = actionlib.SimpleActionServer(
            f"/{arm}/arm_controller/follow_joint_trajectory",
            msgs["FollowJointTrajectoryAction"],
            execute_cb=execute,
            auto_start=False,
        )
        server.start()
        return server

    def close(self) -> None:
        self.stop_threads()
        if self._started:
            self._started = False
            for s in self._services:
                s.shutdown("agrisim stopped")
            self.rospy.signal_shutdown("agrisim stopped")

    # ------------------------------------------------------------------ ROS 1's messages
    def now(self) -> Any:
        return self.rospy.Time.now()

    def send(self, publisher: Any, message: Any) -> None:
        publisher.publish(message)

    def _header(self, frame: str, stamp: Any) -> Any:
        from std_msgs.msg import Header

        return Header(stamp=stamp, frame_id=frame)

    def joint_state(self, stamp: Any, names: list[str], q: list[float], qd: list[float]) -> Any:
        from sensor_msgs.msg import JointState

        return JointState(header=self._header("", stamp), name=names, position=q, velocity=qd)

    def transform(self, parent: str, child: str, stamp: Any, xyz: list[float], quat: list[float]) -> Any:
        from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3

        return TransformStamped(
            header=self._header(parent, stamp),
            child_frame_id=child,
            transform=Transform(translation=Vector3(*xyz), rotation=Quaternion(*quat)),
        )

    def tf_message(self, transforms: list[Any]) -> Any:
        from tf2_msgs.msg import TFMessage

        return TFMessage(transforms=transforms)

    def image(self, frame: str, stamp: Any, height: int, width: int, encoding: str, step: int, data: bytes) -> Any:
        from sensor_msgs.msg import Image

        return Image(
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
        from sensor_msgs.msg import CameraInfo

        return CameraInfo(
            header=self._header(frame, stamp),
            height=height,
            width=width,
            distortion_model=lens[0],
            D=list(lens[1]),
            K=K.reshape(-1).tolist(),
            R=np.eye(3).reshape(-1).tolist(),
            P=P.reshape(-1).tolist(),
        )

    def say(self, line: str, level: str) -> None:
        from std_msgs.msg import String

        getattr(self.rospy, f"log{level}")(line)
        self.pub_events.publish(String(data=line))
