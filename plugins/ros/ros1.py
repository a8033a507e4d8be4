"""The ``ros1`` bridge: a live session as a rospy node named ``agrisim`` (topics and services in
:mod:`agrisim.plugins.ros`). rospy runs subscriber callbacks and service handlers on threads of
its own; they queue work for the session's thread and wait for its answer, so a trigger returns
once its view is rendered, published and saved."""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from agrisim import hookimpl
from agrisim.errors import UserError
from agrisim.files.rosbag import rep118
from agrisim.interfaces import Bridge, Capture
from agrisim.live import LiveSession, Refused
from agrisim.records import Run
from agrisim.robot.tf_tree import ArmFrames, quaternions

from . import BridgeOptions
from .rospy_env import import_rospy

if TYPE_CHECKING:
    from types import ModuleType


def preflight(config: Any, options: BridgeOptions) -> None:
    """rospy importable and a ROS master answering, before anything is written."""
    import_rospy()
    import rosgraph

    if not rosgraph.is_master_online():
        raise UserError(f"no ROS master at {rosgraph.get_master_uri()}: start roscore, or set ROS_MASTER_URI")


class Ros1Bridge(Bridge):
    """Serves a :class:`LiveSession` to ROS 1 clients."""

    def __init__(self, session: LiveSession, options: BridgeOptions) -> None:
        self.session, self.options = session, options
        self.arms = [a.name for a in session.cell.arms]
        self.frames = {a.name: ArmFrames(a.name, session.kinematics[a.name], a.urdf) for a in session.cell.arms}
        self._closed = threading.Event()
        self._thread: threading.Thread | None = None
        self._started = False

    # ------------------------------------------------------------------ set-up
    def start(self) -> None:
        rospy = import_rospy()
        from sensor_msgs.msg import CameraInfo, Image, JointState
        from std_msgs.msg import String
        from std_srvs.srv import Trigger
        from tf2_msgs.msg import TFMessage
        from trajectory_msgs.msg import JointTrajectory

        self.rospy: ModuleType = rospy
        # agrisim handles Ctrl-C itself: the session must close and save the run
        rospy.init_node("agrisim", disable_signals=True)
        self._started = True
        P = rospy.Publisher
        self.pub_joints = P("/joint_states", JointState, queue_size=10)
        self.pub_tf = P("/tf", TFMessage, queue_size=100)
        self.pub_tf_static = P("/tf_static", TFMessage, queue_size=1, latch=True)
        self.pub_events = P("/agrisim/events", String, queue_size=100)
        self.pub_arm_joints = {a: P(f"/{a}/joint_states", JointState, queue_size=10) for a in self.arms}
        self.pub_images = {
            a: {
                kind: P(f"/{a}/camera/{kind}", Image, queue_size=2, latch=True)
                for kind in ("image_raw", "depth", "labels", "instances")
            }
            for a in self.arms
        }
        self.pub_info = {a: P(f"/{a}/camera/camera_info", CameraInfo, queue_size=2, latch=True) for a in self.arms}
        self.pub_tf_static.publish(TFMessage(transforms=self._static_transforms()))
        self._subs = [
            rospy.Subscriber(
                f"/{a}/arm_controller/command", JointTrajectory, self._on_trajectory, callback_args=a, queue_size=10
            )
            for a in self.arms
        ]
        self._services = [
            rospy.Service(f"/{a}/capture", Trigger, lambda req, a=a: self._on_capture(a)) for a in self.arms
        ]
        self.session.pm.register(self, name="bridge:ros1")
        self._thread = threading.Thread(target=self._publish_state, name="agrisim-ros1-state", daemon=True)
        self._thread.start()

    def describe(self) -> list[str]:
        lines = ["/joint_states, /tf, /tf_static, /agrisim/events"]
        for a in self.arms:
            lines.append(
                f"/{a}/arm_controller/command (in), /{a}/capture (std_srvs/Trigger), /{a}/joint_states, "
                f"/{a}/camera/{{image_raw,depth,labels,instances,camera_info}}"
            )
        return lines

    def close(self) -> None:
        self._closed.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None
        if self.session.pm.is_registered(self):
            self.session.pm.unregister(self)
        if self._started:
            self._started = False
            for s in self._services:
                s.shutdown("agrisim stopped")
            self.rospy.signal_shutdown("agrisim stopped")

    # ------------------------------------------------------------------ out
    def _header(self, frame: str, stamp: Any) -> Any:
        from std_msgs.msg import Header

        return Header(stamp=stamp, frame_id=frame)

    def _transforms(self, edges: list[tuple[str, str]], T: np.ndarray, stamp: Any) -> list[Any]:
        from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3

        out = []
        for (parent, child), Ti, qi in zip(edges, T, quaternions(T), strict=True):
            x, y, z = (float(v) for v in Ti[:3, 3])
            out.append(
                TransformStamped(
                    header=self._header(parent, stamp),
                    child_frame_id=child,
                    transform=Transform(translation=Vector3(x, y, z), rotation=Quaternion(*(float(v) for v in qi))),
                )
            )
        return out

    def _static_transforms(self) -> list[Any]:
        stamp = self.rospy.Time.now()
        out = []
        for a, frames in self.frames.items():
            edges, T = frames.static(np.asarray(self.session.cell.arm(a).home, float))
            out += self._transforms(edges, T, stamp)
        return out

    def _publish_state(self) -> None:
        """/joint_states and /tf at the rate, from where the arms are on the wall clock."""
        from sensor_msgs.msg import JointState
        from tf2_msgs.msg import TFMessage

        period = 1.0 / self.options.rate
        tick = time.monotonic()
        while not self._closed.is_set():
            state = self.session.motion.state()
            stamp = self.rospy.Time.now()
            names, q_all, qd_all, transforms = [], [], [], []
            for a in self.arms:
                q, qd = state[a]
                joints = self.session.joint_names(a)
                velocity = [] if np.isnan(qd).any() else [float(v) for v in qd]
                self.pub_arm_joints[a].publish(
                    JointState(
                        header=self._header("", stamp), name=joints, position=[float(v) for v in q], velocity=velocity
                    )
                )
                names += [f"{a}/{j}" for j in joints]
                q_all += [float(v) for v in q]
                qd_all += velocity if velocity else [0.0] * len(q)
                transforms += self._transforms(self.frames[a].moving_edges, self.frames[a].moving(q), stamp)
            self.pub_joints.publish(
                JointState(header=self._header("", stamp), name=names, position=q_all, velocity=qd_all)
            )
            self.pub_tf.publish(TFMessage(transforms=transforms))
            tick += period
            self._closed.wait(max(0.0, tick - time.monotonic()))
            tick = max(tick, time.monotonic() - period)  # a stall is not made up with a burst

    def _image(self, frame: str, stamp: Any, pixels: np.ndarray, encoding: str) -> Any:
        from sensor_msgs.msg import Image

        pixels = np.ascontiguousarray(pixels)
        if pixels.dtype.byteorder == ">":
            pixels = pixels.astype(pixels.dtype.newbyteorder("<"))
        return Image(
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
        from sensor_msgs.msg import CameraInfo

        images = capture.images
        if images is None or capture.robot not in self.pub_images:
            return
        stamp = self.rospy.Time.now()
        frame = f"{capture.robot}/camera_optical_frame"
        K = np.asarray(capture.camera.K, float)
        P = np.zeros((3, 4))
        P[:, :3] = K
        self.pub_info[capture.robot].publish(
            CameraInfo(
                header=self._header(frame, stamp),
                height=int(images.rgb.shape[0]),
                width=int(images.rgb.shape[1]),
                distortion_model="plumb_bob",
                D=[0.0] * 5,
                K=K.reshape(-1).tolist(),
                R=np.eye(3).reshape(-1).tolist(),
                P=P.reshape(-1).tolist(),
            )
        )
        pub = self.pub_images[capture.robot]
        pub["depth"].publish(self._image(frame, stamp, rep118(images.depth), "32FC1"))
        pub["labels"].publish(self._image(frame, stamp, images.labels.astype(np.uint8), "mono8"))
        if images.instances is not None:
            pub["instances"].publish(self._image(frame, stamp, images.instances.astype(np.uint16), "mono16"))
        pub["image_raw"].publish(self._image(frame, stamp, images.rgb, "rgb8"))

    def _event(self, line: str, level: str = "info") -> None:
        from std_msgs.msg import String

        getattr(self.rospy, f"log{level}")(line)
        self.pub_events.publish(String(data=line))

    # ------------------------------------------------------------------ in
    def _on_trajectory(self, msg: Any, arm: str) -> None:
        names = [n.removeprefix(f"{arm}/") for n in msg.joint_names]
        times = [p.time_from_start.to_sec() for p in msg.points]
        positions = [list(p.positions) for p in msg.points]
        velocities = [list(p.velocities) for p in msg.points]
        s = self.session
        try:
            result = s.submit(lambda: s.execute(arm, names, times, positions, velocities)).result()
        except Refused as exc:
            self._event(f"refused: {exc}", "warn")
            return
        except Exception as exc:  # a backend's failure: reported, and the session goes on
            self._event(f"failed: {arm} trajectory: {type(exc).__name__}: {exc}", "err")
            return
        outcome = "reached" if result.reached else f"not reached: {result.reason}"
        self._event(f"done: {arm} trajectory {result.frame} ({result.duration_s:.3f} s simulated), {outcome}")

    def _on_capture(self, arm: str) -> Any:
        from std_srvs.srv import TriggerResponse

        s = self.session
        try:
            capture = s.submit(lambda: s.capture(arm)).result()
        except Refused as exc:
            self._event(f"refused: {exc}", "warn")
            return TriggerResponse(success=False, message=str(exc))
        except Exception as exc:
            self._event(f"failed: {arm} capture: {type(exc).__name__}: {exc}", "err")
            return TriggerResponse(success=False, message=f"{type(exc).__name__}: {exc}")
        self._event(f"done: {arm} view {capture.frame}")
        return TriggerResponse(success=True, message=capture.frame)
