"""What both ROS bridges do, whatever carries the messages: the arms' state at the rate, the views
as images, trajectories and triggers turned into the session's commands and their outcomes into
one line each. A bridge supplies the messages of its ROS and how they are sent."""

from __future__ import annotations

import threading
import time
from abc import abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np

from agrisim import hookimpl
from agrisim.interfaces import Bridge, Capture
from agrisim.plugins.ros.live import LiveSession, Refused
from agrisim.plugins.ros.tf_tree import ArmFrames, quaternions
from agrisim.records import Run
from agrisim.scene.calibration import ros_distortion
from agrisim.scene.encoding import rep118

from . import BridgeOptions

#: the camera topics of each arm, by the image they carry
IMAGE_TOPICS = ("image_raw", "depth", "labels", "instances", "depth_truth")


class RosBridge(Bridge):
    """A live session served to ROS clients; subclasses carry the messages."""

    def __init__(self, session: LiveSession, options: BridgeOptions) -> None:
        self.session, self.options = session, options
        self.arms = [a.name for a in session.cell.arms]
        self.frames = {a.name: ArmFrames(a.name, session.kinematics[a.name], a.urdf) for a in session.cell.arms}
        self._closed = threading.Event()
        self._threads: list[threading.Thread] = []
        # publishers, filled in by the subclass's start()
        self.pub_joints: Any = None
        self.pub_tf: Any = None
        self.pub_tf_static: Any = None
        self.pub_arm_joints: dict[str, Any] = {}
        self.pub_images: dict[str, dict[str, Any]] = {}
        self.pub_info: dict[str, Any] = {}

    # ------------------------------------------------------------------ what a subclass supplies
    @abstractmethod
    def now(self) -> Any:
        """The stamp of a message sent now."""

    @abstractmethod
    def send(self, publisher: Any, message: Any) -> None:
        """Publish ``message``."""

    @abstractmethod
    def joint_state(self, stamp: Any, names: list[str], q: list[float], qd: list[float]) -> Any: ...

    @abstractmethod
    def transform(self, parent: str, child: str, stamp: Any, xyz: list[float], quat: list[float]) -> Any:
        """A TransformStamped; ``quat`` is (x, y, z, w)."""

    @abstractmethod
    def tf_message(self, transforms: list[Any]) -> Any: ...

    @abstractmethod
    def image(self, frame: str, stamp: Any, height: int, width: int, encoding: str, step: int, data: bytes) -> Any: ...

    @abstractmethod
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
        """``sensor_msgs/CameraInfo``; ``lens`` is its (``distortion_model``, ``D``)."""

    @abstractmethod
    def say(self, line: str, level: str) -> None:
        """One line about a command (``level``: info, warn, err), on ``/agrisim/events`` and in
        the log."""

    def describe(self) -> list[str]:
        lines = ["/joint_states, /tf, /tf_static, /agrisim/events"]
        for a in self.arms:
            lines.append(
                f"{self.command_topic(a)} (in), /{a}/capture (std_srvs/Trigger), /{a}/joint_states, "
                f"/{a}/camera/{{image_raw,depth,labels,instances,camera_info}}"
            )
        return lines

    @abstractmethod
    def command_topic(self, arm: str) -> str:
        """Where the arm's trajectories come in."""

    # ------------------------------------------------------------------ shared
    def start_threads(self, *targets: tuple[Any, str]) -> None:
        """Register for the views and start the state publisher (and ``targets``)."""
        self.session.pm.register(self, name=f"bridge:{type(self).__name__}")
        for target, name in ((self._publish_state, "state"), *targets):
            thread = threading.Thread(target=target, name=f"agrisim-ros-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop_threads(self) -> None:
        self._closed.set()
        for thread in self._threads:
            thread.join(timeout=5)
        self._threads = []
        if self.session.pm.is_registered(self):
            self.session.pm.unregister(self)

    def transforms(self, edges: list[tuple[str, str]], T: np.ndarray, stamp: Any) -> list[Any]:
        return [
            self.transform(parent, child, stamp, [float(v) for v in Ti[:3, 3]], [float(v) for v in qi])
            for (parent, child), Ti, qi in zip(edges, T, quaternions(T), strict=True)
        ]

    def static_transforms(self) -> Any:
        """``/tf_static``'s message: ``world`` -> each arm's base and every fixed joint."""
        stamp = self.now()
        out = []
        for a, frames in self.frames.items():
            edges, T = frames.static(np.asarray(self.session.cell.arm(a).home, float))
            out += self.transforms(edges, T, stamp)
        return self.tf_message(out)

    def _publish_state(self) -> None:
        """/joint_states and /tf at the rate, from where the arms are on the wall clock."""
        period = 1.0 / self.options.rate
        tick = time.monotonic()
        while not self._closed.is_set():
            state = self.session.motion.state()
            stamp = self.now()
            names, q_all, qd_all, transforms = [], [], [], []
            for a in self.arms:
                q, qd = state[a]
                joints = self.session.joint_names(a)
                velocity = [] if np.isnan(qd).any() else [float(v) for v in qd]
                self.send(self.pub_arm_joints[a], self.joint_state(stamp, joints, [float(v) for v in q], velocity))
                names += [f"{a}/{j}" for j in joints]
                q_all += [float(v) for v in q]
                qd_all += velocity if velocity else [0.0] * len(q)
                transforms += self.transforms(self.frames[a].moving_edges, self.frames[a].moving(q), stamp)
            self.send(self.pub_joints, self.joint_state(stamp, names, q_all, qd_all))
            self.send(self.pub_tf, self.tf_message(transforms))
            tick += period
            self._closed.wait(max(0.0, tick - time.monotonic()))
            tick = max(tick, time.monotonic() - period)  # a stall is not made up with a burst

    def _image(self, frame: str, stamp: Any, pixels: np.ndarray, encoding: str) -> Any:
        pixels = np.ascontiguousarray(pixels)
        if pixels.dtype.byteorder == ">":
            pixels = pixels.astype(pixels.dtype.newbyteorder("<"))
        h, w = pixels.shape[:2]
        return self.image(frame, stamp, h, w, encoding, int(pixels.strides[0]), pixels.tobytes())

    @hookimpl
    def agrisim_capture(self, run: Run, capture: Capture) -> None:
        """Every view, the session's and the routine's, on the arm's camera topics."""
        images = capture.images
        if images is None or capture.robot not in self.pub_images:
            return
        stamp = self.now()
        frame = f"{capture.robot}/camera_optical_frame"
        K = np.asarray(capture.camera.K, float)
        P = np.zeros((3, 4))
        P[:, :3] = K
        h, w = images.rgb.shape[:2]
        lens = ros_distortion(capture.camera.distortion)
        self.send(self.pub_info[capture.robot], self.camera_info(frame, stamp, h, w, K, P, lens))
        pub = self.pub_images[capture.robot]
        # a depth sensor's measurement is the camera's depth, as a robot's driver publishes it;
        # the exact depth then goes beside it
        if images.depth_sensor is None:
            self.send(pub["depth"], self._image(frame, stamp, rep118(images.depth), "32FC1"))
        else:
            self.send(pub["depth"], self._image(frame, stamp, rep118(images.depth_sensor), "32FC1"))
            self.send(pub["depth_truth"], self._image(frame, stamp, rep118(images.depth), "32FC1"))
        self.send(pub["labels"], self._image(frame, stamp, images.labels.astype(np.uint8), "mono8"))
        if images.instances is not None:
            self.send(pub["instances"], self._image(frame, stamp, images.instances.astype(np.uint16), "mono16"))
        self.send(pub["image_raw"], self._image(frame, stamp, images.rgb, "rgb8"))

    def run_trajectory(
        self,
        arm: str,
        names: Sequence[str],
        times: Sequence[float],
        positions: Sequence[Sequence[float]],
        velocities: Sequence[Sequence[float]],
    ) -> tuple[str, str]:
        """A trajectory message's content, executed by the session; its outcome said, and
        returned: (``reached``, ``not reached``, ``refused:joints``, ``refused:goal`` or
        ``failed``; the line)."""
        names = [n.removeprefix(f"{arm}/") for n in names]
        s = self.session
        try:
            result = s.submit(lambda: s.execute(arm, names, times, positions, velocities)).result()
        except Refused as exc:
            self.say(f"refused: {exc}", "warn")
            return f"refused:{exc.kind}", f"refused: {exc}"
        except Exception as exc:  # a backend's failure: reported, and the session goes on
            line = f"failed: {arm} trajectory: {type(exc).__name__}: {exc}"
            self.say(line, "err")
            return "failed", line
        outcome = "reached" if result.reached else f"not reached: {result.reason}"
        line = f"done: {arm} trajectory {result.frame} ({result.duration_s:.3f} s simulated), {outcome}"
        self.say(line, "info")
        return ("reached" if result.reached else "not reached"), line

    def take_view(self, arm: str) -> tuple[bool, str]:
        """A trigger: (success, the frame's name or why not)."""
        s = self.session
        try:
            capture = s.submit(lambda: s.capture(arm)).result()
        except Refused as exc:
            self.say(f"refused: {exc}", "warn")
            return False, str(exc)
        except Exception as exc:
            self.say(f"failed: {arm} capture: {type(exc).__name__}: {exc}", "err")
            return False, f"{type(exc).__name__}: {exc}"
        self.say(f"done: {arm} view {capture.frame}", "info")
        return True, capture.frame
