"""The ``rosbag`` exporter: ``RUN_DIR/rosbag/`` or the ``OUT`` folder named (rosbag2 format 9:
``rosbag.mcap`` and the ``metadata.yaml`` that ``ros2 bag info`` reads), written without ROS by
the ``rosbags`` library.

Why ``rosbags``: it writes the rosbag2 directory (MCAP storage, zstd-compressed chunks, the
metadata file with per-topic QoS) and serialises messages with the ROS 2 message definitions it
ships (Jazzy's), in pure Python; ``mcap`` + ``mcap-ros2-support`` write the MCAP file alone and
would leave ``metadata.yaml`` and the definitions to us.

Every stamp is simulated time, seconds since the run started (``header.stamp`` equals the
message's log time; play it with ``ros2 bag play --clock``). Topics, for each arm ``A``
(``r1``, ``r2``):

- ``/tf_static`` (``tf2_msgs/TFMessage``, transient local, once at 0): ``world`` ->
  ``A/world`` (where the arm's base stands) and every fixed joint of the arm's URDF (base, flange,
  camera body, ``A/camera_optical_frame``).
- ``/tf`` (``tf2_msgs/TFMessage``): every revolute joint of every arm, at every stamp of the
  timeline (below), as ``robot_state_publisher`` would send them.
- ``/A/joint_states`` (``sensor_msgs/JointState``): the six joints at every stamp; positions
  in radians, velocities in rad/s where the physics reported them (else empty).
- ``/A/planned_trajectory`` (``trajectory_msgs/JointTrajectory``): each planned move, stamped
  at its start, points every 1/240 s with positions and velocities.
- ``/A/camera/image_raw`` (``rgb8``), ``/A/camera/depth`` (``32FC1``, planar z in metres, REP
  118; +Inf where nothing was hit, REP 117's "no return"; a depth sensor's measurement where the
  run has one, the exact depth then on ``/A/camera/depth_truth``), ``/A/camera/labels`` (``mono8`` label
  ids), ``/A/camera/instances`` (``mono16`` leaf ids, where the run numbers leaves),
  ``/A/camera/plants`` (``mono16``, a bench's: which plant, 0 none) and ``/A/camera/camera_info``
  (K, P, the lens's distortion): one each per rendered frame, in ``A/camera_optical_frame``
  (OpenCV axes, which are ROS's optical-frame axes).
- ``/reconstruction/cloud`` (``sensor_msgs/PointCloud2`` in ``world``): the merged clouds of
  every label, fields ``x y z`` (float32), ``rgb`` (PCL's packed float) and ``label`` (uint8), at
  the last frame's stamp.

The timeline is every sample the physics reported for any arm (``trajectories/``), every
capture and 0; between its own samples an arm holds its last one, so TF is complete at every
stamp and at each image's stamp equals the pose it was rendered from. The bag's custom data
holds the label table (``agrisim.labels``, JSON) and a bench's plants (``agrisim.bench``, JSON:
the rows of :mod:`agrisim.plugins.sinks.dataset.bench`, whose ids ``plants`` holds).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from agrisim import BackendSpec, hookimpl
from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.files.atomic import staged_dir
from agrisim.files.rundir import read_json, read_run
from agrisim.interfaces import Exporter
from agrisim.plugins.ros.tf_tree import WORLD, ArmFrames, quaternions
from agrisim.plugins.sinks.dataset.bench import bench_rows, read_bench
from agrisim.scene.calibration import ros_distortion
from agrisim.scene.encoding import rep118

ROSBAG_DIR = layout.ROSBAG
CLOUD_TOPIC = "/reconstruction/cloud"


@dataclass
class ArmTrack:
    """One arm's joint samples over the whole run, in time order (all its moves' executed
    samples): ``t_ns`` (N,), ``q`` (N x dof), ``qd`` (N x dof, NaN rows where the physics
    reported no velocity)."""

    joints: list[str]
    t_ns: np.ndarray
    q: np.ndarray
    qd: np.ndarray


def to_ns(t: ArrayLike) -> Any:
    """Seconds to integer nanoseconds (the bag's clock)."""
    return np.rint(np.asarray(t, float) * 1e9).astype(np.int64)


def read_moves(run_dir: Path, run: dict[str, Any], joints: dict[str, list[str]]) -> dict[str, list[dict[str, Any]]]:
    """Every arm's moves (``trajectories/<frame>.json``), in time order, checked: a run written
    before trajectories were kept, a missing or malformed file is refused, naming it."""
    folder = run_dir / layout.TRAJECTORIES
    if not folder.is_dir() and run.get("results"):
        raise UserError(
            f"the run in {run_dir} has no {layout.TRAJECTORIES}/ (it predates them): run it again to export it"
        )
    for frame in run.get("frames_complete") or []:
        if not layout.trajectory(run_dir, frame).is_file():
            raise UserError(f"missing {layout.trajectory(run_dir, frame)}: the run's trajectories are incomplete")
    moves: dict[str, list[dict[str, Any]]] = {arm: [] for arm in joints}
    for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        doc = read_json(path, "")
        arm = doc.get("robot")
        if arm not in moves:
            raise UserError(f"{path} is for robot {arm!r}, not one of the run's arms {sorted(moves)}")
        if list(doc.get("joints") or []) != joints[arm]:
            raise UserError(f"{path} names joints {doc.get('joints')}, not {joints[arm]}")
        try:
            for part in ("planned", "executed"):
                n = len(doc[part]["t"])
                for key in ("q", "qd"):
                    if doc[part].get(key) is not None and np.shape(doc[part][key]) != (n, len(joints[arm])):
                        raise ValueError(f"{part} {key} is not {n} x {len(joints[arm])}")
        except (KeyError, TypeError, ValueError) as exc:
            raise UserError(f"{path} is not an agrisim trajectory: {exc}") from None
        moves[arm].append(doc)
    for docs in moves.values():
        docs.sort(key=lambda d: d["executed"]["t"][0] if d["executed"]["t"] else 0.0)
    return moves


def arm_track(moves: list[dict[str, Any]], home: np.ndarray, joints: list[str]) -> ArmTrack:
    """One arm's samples: ``home`` at 0, then every executed sample of its ``moves``."""
    dof = len(joints)
    t, q, qd = [np.zeros(1, np.int64)], [np.asarray(home, float)[None, :]], [np.zeros((1, dof))]
    for doc in moves:
        ex = doc["executed"]
        if not ex["t"]:
            continue
        t.append(to_ns(ex["t"]))
        q.append(np.asarray(ex["q"], float))
        qd.append(np.asarray(ex["qd"], float) if ex.get("qd") is not None else np.full((len(ex["t"]), dof), np.nan))
    return ArmTrack(joints, np.concatenate(t), np.concatenate(q), np.concatenate(qd))


class BagMessages:
    """The rosbags message types of one type store, and builders for agrisim's data."""

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.store = get_typestore(Stores.ROS2_JAZZY)
        t = self.store.types
        self.Time, self.Header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
        self.Duration = t["builtin_interfaces/msg/Duration"]
        self.TFMessage, self.TransformStamped = t["tf2_msgs/msg/TFMessage"], t["geometry_msgs/msg/TransformStamped"]
        self.Transform, self.Vector3, self.Quaternion = (
            t["geometry_msgs/msg/Transform"],
            t["geometry_msgs/msg/Vector3"],
            t["geometry_msgs/msg/Quaternion"],
        )
        self.JointState, self.Image, self.CameraInfo = (
            t["sensor_msgs/msg/JointState"],
            t["sensor_msgs/msg/Image"],
            t["sensor_msgs/msg/CameraInfo"],
        )
        self.RegionOfInterest = t["sensor_msgs/msg/RegionOfInterest"]
        self.PointCloud2, self.PointField = t["sensor_msgs/msg/PointCloud2"], t["sensor_msgs/msg/PointField"]
        self.JointTrajectory = t["trajectory_msgs/msg/JointTrajectory"]
        self.JointTrajectoryPoint = t["trajectory_msgs/msg/JointTrajectoryPoint"]

    def header(self, stamp_ns: int, frame: str) -> Any:
        return self.Header(
            stamp=self.Time(sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000)), frame_id=frame
        )

    def transforms(self, stamp_ns: int, edges: list[tuple[str, str]], T: np.ndarray, quat: np.ndarray) -> list[Any]:
        """TransformStamped of each (parent, child) edge with its 4x4 ``T[i]`` and (x, y, z, w)
        quaternion ``quat[i]``."""
        header = {}
        out = []
        for (parent, child), Ti, qi in zip(edges, T, quat, strict=True):
            if parent not in header:
                header[parent] = self.header(stamp_ns, parent)
            x, y, z = (float(v) for v in Ti[:3, 3])
            out.append(
                self.TransformStamped(
                    header=header[parent],
                    child_frame_id=child,
                    transform=self.Transform(
                        translation=self.Vector3(x=x, y=y, z=z),
                        rotation=self.Quaternion(x=float(qi[0]), y=float(qi[1]), z=float(qi[2]), w=float(qi[3])),
                    ),
                )
            )
        return out

    def image(self, stamp_ns: int, frame: str, pixels: np.ndarray, encoding: str) -> Any:
        """An ``Image`` of an H x W (x C) array, little-endian, rows packed."""
        pixels = np.ascontiguousarray(pixels)
        if pixels.dtype.byteorder == ">":
            pixels = pixels.astype(pixels.dtype.newbyteorder("<"))
        h, w = pixels.shape[:2]
        return self.Image(
            header=self.header(stamp_ns, frame),
            height=h,
            width=w,
            encoding=encoding,
            is_bigendian=0,
            step=int(pixels.strides[0]),
            data=pixels.reshape(-1).view(np.uint8),
        )

    def camera_info(self, stamp_ns: int, frame: str, intrinsics: dict[str, Any]) -> Any:
        K = np.asarray(intrinsics["K"], float)
        P = np.zeros((3, 4))
        P[:, :3] = K
        model, D = ros_distortion(intrinsics.get("distortion"))
        return self.CameraInfo(
            header=self.header(stamp_ns, frame),
            height=int(intrinsics["height"]),
            width=int(intrinsics["width"]),
            distortion_model=model,
            d=np.asarray(D, float),
            k=K.reshape(-1),
            r=np.eye(3).reshape(-1),
            p=P.reshape(-1),
            binning_x=0,
            binning_y=0,
            roi=self.RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
        )

    def joint_state(self, stamp_ns: int, names: list[str], q: np.ndarray, qd: np.ndarray) -> Any:
        return self.JointState(
            header=self.header(stamp_ns, ""),
            name=names,
            position=np.asarray(q, float),
            velocity=np.zeros(0) if np.isnan(qd).any() else np.asarray(qd, float),
            effort=np.zeros(0),
        )

    def trajectory(self, names: list[str], planned: dict[str, Any]) -> tuple[int, Any]:
        """A planned move as a ``JointTrajectory`` stamped at its start (and that stamp)."""
        t = np.asarray(planned["t"], float)
        q = np.asarray(planned["q"], float).reshape(len(t), len(names))
        qd = np.asarray(planned["qd"], float).reshape(len(t), len(names)) if planned.get("qd") is not None else None
        start = int(to_ns(t[0]))
        offsets = to_ns(t) - start
        points = [
            self.JointTrajectoryPoint(
                positions=q[i],
                velocities=qd[i] if qd is not None else np.zeros(0),
                accelerations=np.zeros(0),
                effort=np.zeros(0),
                time_from_start=self.Duration(
                    sec=int(offsets[i] // 1_000_000_000), nanosec=int(offsets[i] % 1_000_000_000)
                ),
            )
            for i in range(len(t))
        ]
        return start, self.JointTrajectory(header=self.header(start, ""), joint_names=names, points=points)

    def cloud(self, stamp_ns: int, points: np.ndarray, colors: np.ndarray, labels: np.ndarray) -> Any:
        """``PointCloud2``: float32 x, y, z, PCL's packed ``rgb`` (0x00RRGGBB as float32 bits)
        and a uint8 ``label``; 20 bytes a point, unorganised."""
        # the type store's classes are made at run time; its annotations know only the MsgType
        # protocol, not PointField's datatype constants
        F: Any = self.PointField
        rows = np.zeros(len(points), np.dtype([("xyz", "<f4", 3), ("rgb", "<u4"), ("label", "u1"), ("pad", "u1", 3)]))
        rows["xyz"] = points
        c = np.asarray(colors, np.uint32)
        rows["rgb"] = (c[:, 0] << 16) | (c[:, 1] << 8) | c[:, 2]
        rows["label"] = labels
        fields = [
            F(name="x", offset=0, datatype=F.FLOAT32, count=1),
            F(name="y", offset=4, datatype=F.FLOAT32, count=1),
            F(name="z", offset=8, datatype=F.FLOAT32, count=1),
            F(name="rgb", offset=12, datatype=F.FLOAT32, count=1),
            F(name="label", offset=16, datatype=F.UINT8, count=1),
        ]
        return self.PointCloud2(
            header=self.header(stamp_ns, WORLD),
            height=1,
            width=len(points),
            fields=fields,
            is_bigendian=False,
            point_step=rows.itemsize,
            row_step=rows.itemsize * len(points),
            data=rows.view(np.uint8).reshape(-1) if len(points) else np.zeros(0, np.uint8),
            is_dense=True,
        )


def frame_depth(run_dir: Path, frame: str) -> np.ndarray:
    """A saved frame's depth for the bag (the exact EXR when the run kept one)."""
    from agrisim.evaluation.views import load_depth

    return rep118(load_depth(run_dir, frame))


def read_cloud(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Points and uint8 colours of a ``clouds/<label>.ply``."""
    import trimesh

    cloud = trimesh.load(path, file_type="ply", process=False)
    points = np.asarray(getattr(cloud, "vertices", np.zeros((0, 3))), float).reshape(-1, 3)
    colors = getattr(cloud, "colors", None)
    colors = (
        np.asarray(colors, np.uint8)[:, :3]
        if colors is not None and len(colors) == len(points)
        else np.full((len(points), 3), 200, np.uint8)
    )
    return points, colors


class RosbagExport:
    """Everything a bag is made of, read and checked before anything is written."""

    def __init__(self, run_dir: Path) -> None:
        from agrisim.config import build_config
        from agrisim.robot.kinematics import ArmKinematics
        from agrisim.validation import open_rig

        self.run_dir = Path(run_dir)
        self.run, self.cameras = read_run(self.run_dir, rendered=False)
        saved = self.run.get("config")
        if not isinstance(saved, dict):
            raise UserError(f"{self.run_dir / layout.RUN_JSON} holds no run configuration")
        _, cell = open_rig(build_config({k: v for k, v in saved.items() if k != "output"}))
        self.kin = {arm.name: ArmKinematics(arm) for arm in cell.arms}
        self.joints = {arm.name: list(arm.joints) for arm in cell.arms}
        self.moves = read_moves(self.run_dir, self.run, self.joints)
        self.tracks = {
            arm.name: arm_track(self.moves[arm.name], np.asarray(arm.home), self.joints[arm.name]) for arm in cell.arms
        }
        self.frames_of = {arm.name: ArmFrames(arm.name, self.kin[arm.name], arm.urdf) for arm in cell.arms}
        self.frames = dict(sorted((self.cameras.get("frames") or {}).items()))
        self.rendered = bool(self.run.get("frames_complete")) and isinstance(self.run.get("labels"), list)
        labels = self.run.get("labels")
        self.labels: list[Any] = labels if isinstance(labels, list) else []
        self.bench = bench_rows(read_bench(self.run, self.run_dir / layout.RUN_JSON))
        captures = to_ns([float(f["sim_time"]) for f in self.frames.values()]) if self.frames else np.zeros(0, np.int64)
        self.capture_ns = dict(zip(self.frames, (int(c) for c in captures), strict=True))
        self.stamps = np.unique(
            np.concatenate([np.zeros(1, np.int64), captures, *(tr.t_ns for tr in self.tracks.values())])
        )

    # ------------------------------------------------------------------ the arms
    def arm_samples(self, arm: str) -> np.ndarray:
        """For every stamp of the timeline, the index of the arm's sample it holds."""
        return np.searchsorted(self.tracks[arm].t_ns, self.stamps, side="right") - 1

    def moving_transforms(self, arm: str, samples: np.ndarray) -> tuple[list[tuple[str, str]], np.ndarray]:
        """The arm's revolute joints as (parent, child) frames, and ``parent_T_child`` at every
        sample index in ``samples`` (S x J x 4 x 4)."""
        frames, track = self.frames_of[arm], self.tracks[arm]
        return frames.moving_edges, np.stack([frames.moving(track.q[i]) for i in samples])

    def static_transforms(self) -> tuple[list[tuple[str, str]], np.ndarray]:
        """``world`` -> each arm's URDF root and every fixed joint of every arm."""
        edges, T = [], []
        for arm, frames in self.frames_of.items():
            e, t = frames.static(self.tracks[arm].q[0])
            edges += e
            T.append(t)
        return edges, np.concatenate(T)


def _qos_latched() -> Any:
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    never = QosTime(0, 0)  # rosbag2's "default" (unset) duration
    return Qos(
        QosHistory.KEEP_LAST,
        1,
        QosReliability.RELIABLE,
        QosDurability.TRANSIENT_LOCAL,
        never,
        never,
        QosLiveliness.AUTOMATIC,
        never,
        False,
    )


def bag_messages(export: RosbagExport, msgs: BagMessages) -> Iterator[tuple[str, str, int, Any]]:
    """(topic, message type, stamp in ns, message) in time order: at one stamp TF and joint
    states come before the images taken there. Images are read as they are reached."""
    events: list[tuple[int, int, int, str, Any]] = []  # (stamp, order, sequence, kind, what)
    static_edges, static_T = export.static_transforms()
    yield (
        "/tf_static",
        "tf2_msgs/msg/TFMessage",
        0,
        msgs.TFMessage(transforms=msgs.transforms(0, static_edges, static_T, quaternions(static_T))),
    )
    held = {arm: export.arm_samples(arm) for arm in export.tracks}
    moving = {}
    for arm in export.tracks:
        edges, T = export.moving_transforms(arm, np.arange(len(export.tracks[arm].t_ns)))
        moving[arm] = (edges, T, quaternions(T))
    for k, stamp in enumerate(export.stamps):
        events.append((int(stamp), 0, len(events), "state", k))
    for docs in export.moves.values():
        for doc in docs:
            if doc["planned"]["t"]:
                events.append((int(to_ns(doc["planned"]["t"][0])), 1, len(events), "plan", doc))
    if export.rendered:
        for frame, stamp in export.capture_ns.items():
            events.append((stamp, 2, len(events), "frame", frame))
        if any(layout.cloud(export.run_dir, row["name"]).is_file() for row in export.labels if int(row["id"]) != 0):
            events.append((int(export.stamps[-1]), 3, len(events), "cloud", None))
    events.sort(key=lambda e: e[:3])
    from agrisim.evaluation.views import load_frame
    from agrisim.files.rundir import camera_from_json

    intrinsics = export.cameras["intrinsics"]
    camera = camera_from_json(intrinsics) if export.rendered else None
    for stamp, _, _, kind, what in events:
        if kind == "state":
            transforms = []
            for arm, track in export.tracks.items():
                i = held[arm][what]
                edges, T, quat = moving[arm]
                transforms += msgs.transforms(stamp, edges, T[i], quat[i])
                yield (
                    f"/{arm}/joint_states",
                    "sensor_msgs/msg/JointState",
                    stamp,
                    msgs.joint_state(stamp, track.joints, track.q[i], track.qd[i]),
                )
            yield "/tf", "tf2_msgs/msg/TFMessage", stamp, msgs.TFMessage(transforms=transforms)
        elif kind == "plan":
            arm = what["robot"]
            start, message = msgs.trajectory(export.joints[arm], what["planned"])
            yield f"/{arm}/planned_trajectory", "trajectory_msgs/msg/JointTrajectory", start, message
        elif kind == "frame":
            assert camera is not None  # frames are listed only for a rendered run
            arm = export.frames[what]["robot"]
            optical = f"{arm}/{export.kin[arm].arm.camera_frame}"
            images = load_frame(export.run_dir, what, camera)
            yield (
                f"/{arm}/camera/camera_info",
                "sensor_msgs/msg/CameraInfo",
                stamp,
                msgs.camera_info(stamp, optical, intrinsics),
            )
            yield (
                f"/{arm}/camera/image_raw",
                "sensor_msgs/msg/Image",
                stamp,
                msgs.image(stamp, optical, images.rgb, "rgb8"),
            )
            # a depth sensor's measurement is the camera's depth (as a robot's driver publishes
            # it), the exact depth beside it
            measured = images.depth if images.depth_sensor is None else images.depth_sensor
            yield (
                f"/{arm}/camera/depth",
                "sensor_msgs/msg/Image",
                stamp,
                msgs.image(stamp, optical, rep118(measured), "32FC1"),
            )
            if images.depth_sensor is not None:
                yield (
                    f"/{arm}/camera/depth_truth",
                    "sensor_msgs/msg/Image",
                    stamp,
                    msgs.image(stamp, optical, rep118(images.depth), "32FC1"),
                )
            yield (
                f"/{arm}/camera/labels",
                "sensor_msgs/msg/Image",
                stamp,
                msgs.image(stamp, optical, images.labels, "mono8"),
            )
            for name, ids in (("instances", images.instances), ("plants", images.plants)):  # uint16 ids
                if ids is not None:
                    yield (
                        f"/{arm}/camera/{name}",
                        "sensor_msgs/msg/Image",
                        stamp,
                        msgs.image(stamp, optical, ids, "mono16"),
                    )
        else:
            points, colors, labels = [np.zeros((0, 3))], [np.zeros((0, 3), np.uint8)], [np.zeros(0, np.uint8)]
            for row in export.labels:
                path = layout.cloud(export.run_dir, row["name"])
                if int(row["id"]) != 0 and path.is_file():
                    p, c = read_cloud(path)
                    points.append(p)
                    colors.append(c)
                    labels.append(np.full(len(p), int(row["id"]), np.uint8))
            yield (
                CLOUD_TOPIC,
                "sensor_msgs/msg/PointCloud2",
                stamp,
                msgs.cloud(stamp, np.concatenate(points), np.concatenate(colors), np.concatenate(labels)),
            )


def write_rosbag(
    run_dir: Path,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
    out: Path | None = None,
) -> Path:
    """Write the bag's folder ``out`` (default ``run_dir/rosbag/``); an existing one needs
    ``overwrite`` and is replaced only once the new bag is complete. Returns the bag's folder."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    run_dir = Path(run_dir)
    out = run_dir / ROSBAG_DIR if out is None else Path(out)
    if out.exists() and not overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out} is not a directory; the ROS 2 bag export is a folder")
    export = RosbagExport(run_dir)
    msgs = BagMessages()
    with staged_dir(out) as staging:
        # (rosbags creates the bag's own folder: a subfolder of the staged one, moved up after)
        writer = Writer(staging / ROSBAG_DIR, version=9, storage_plugin=StoragePlugin.MCAP)
        # MCAP's own chunk compression: Foxglove and ros2 bag read it transparently
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        writer.set_custom_data("agrisim.labels", json.dumps(export.labels))
        writer.set_custom_data("agrisim.run", str(run_dir.resolve()))
        if export.bench:
            writer.set_custom_data("agrisim.bench", json.dumps(export.bench))
        connections: dict[str, Any] = {}
        total = len(export.stamps) + len(export.frames)
        done = 0
        with writer:
            for topic, msgtype, stamp, message in bag_messages(export, msgs):
                if topic not in connections:
                    qos = [_qos_latched()] if topic == "/tf_static" else []
                    connections[topic] = writer.add_connection(
                        topic, msgtype, typestore=msgs.store, offered_qos_profiles=qos
                    )
                writer.write(connections[topic], stamp, msgs.store.serialize_cdr(message, msgtype))
                if topic == "/tf" or topic.endswith("/image_raw"):
                    done += 1
                    if progress is not None and (done % 500 == 0 or done == total):
                        progress(done, total)
        for item in (staging / ROSBAG_DIR).iterdir():
            os.replace(item, staging / item.name)
        (staging / ROSBAG_DIR).rmdir()
    return out


class RosbagExporter(Exporter):
    """``agrisim export rosbag RUN_DIR [OUT]``: OUT is the bag's folder (default ``RUN_DIR/rosbag``)."""

    default_out = ROSBAG_DIR
    progress_unit = "stamps and frames"

    def export(
        self,
        run_dir: Path,
        out: Path,
        overwrite: bool = False,
        progress: Callable[[int, int], None] | None = None,
    ) -> Path:
        return write_rosbag(run_dir, overwrite, progress, out)

    def summary(self, written: Path) -> str:
        return f"wrote {written} (ros2 bag info {written}; open {written / 'rosbag.mcap'} in Foxglove)"


@hookimpl
def agrisim_exporters() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="rosbag",
            factory=RosbagExporter,
            description="a ROS 2 bag (rosbag2, MCAP, without ROS): TF, joint states, planned trajectories, camera "
            "images, depth (REP 118), labels, instances, camera_info and the reconstructed clouds, in simulated time",
            limits="ROS 2 (Jazzy's message definitions) only, no ROS 1 bag",
        )
    ]
