"""The sink object: one Rerun recording stream per run, fed by the episode's event hooks."""

from __future__ import annotations

import importlib.util
import json
import logging
import socket
from collections.abc import Mapping, Sequence
from datetime import timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlparse

import numpy as np

from agrisim import hookimpl
from agrisim.plugins.render import robot_meshes
from agrisim.scene.colour import linear_to_srgb
from agrisim.scene.encoding import depth_to_mm

from .entities import (
    APPLICATION_ID,
    IMAGE_PLANE_DISTANCE,
    MERGED_CLOUD_POINTS,
    OBSTACLE_COLORS,
    PATH_RATE,
    PRIMITIVE_COLOR,
    RGB_JPEG_QUALITY,
    SETPOINT_ARROW,
    STAND_COLOR,
    STATUS_COLORS,
    TIMELINE_SETPOINT,
    TIMELINE_SIM_TIME,
    TRANSFORM_RATE,
    VIEW_CLOUD_POINTS,
    decimate,
    paths,
    quaternions_xyzw,
    recording_id,
    rgba255,
    robot_color,
)

if TYPE_CHECKING:
    import rerun as rr

    from agrisim.interfaces import Capture, Frame, Trajectory
    from agrisim.records import Run, RunSummary, SetpointResult
    from agrisim.robot.cell import Box, Cylinder
    from agrisim.scene.model import Scene

    from .options import RerunOptions

log = logging.getLogger(__name__)

#: port of the viewer started by ``--spawn`` (Rerun's default)
SPAWN_PORT = 9876
#: seconds to wait for the sinks (file, viewer) to take the last data at the end of the run
FLUSH_TIMEOUT = 20.0
#: a recording written only to a file is batched into large chunks (what ``rerun rrd optimize``
#: would make of it afterwards): small rows wait up to this long before they are written (a
#: run killed outright loses at most this much of them; Ctrl-C and errors flush everything)
FILE_FLUSH_TICK_S = 60.0
#: ...and a chunk is cut at this size (the 2 MiB that ``rerun rrd stats`` takes as its target)
FILE_CHUNK_BYTES = 2 << 20
#: arm transform rows held back per link before they are sent as one column chunk (file only)
ARM_ROWS_PER_CHUNK = 4096


def _time_columns(setpoint: np.ndarray, sim_time: np.ndarray) -> list[Any]:
    seq = np.asarray(setpoint, np.int64)
    return [
        rr.TimeColumn(TIMELINE_SETPOINT, sequence=seq),
        rr.TimeColumn(TIMELINE_SIM_TIME, duration=np.asarray(sim_time, float)),
    ]


def _listening(port: int, host: str = "127.0.0.1") -> bool:
    try:
        with socket.create_connection((host, port), timeout=1.0):
            return True
    except OSError:
        return False


def _load_rerun() -> None:
    # Imported on first use: rerun costs ~0.3 s to import, which runs without a recording
    # (--no-rrd, `agrisim plugins`) should not pay just because this plugin is registered.
    global rr, rrb
    import rerun as rr
    import rerun.blueprint as rrb


class RerunSink:
    """Records one run. Built by the ``rerun`` sink factory; the stream opens at run start."""

    def __init__(self, run: Run, options: RerunOptions) -> None:
        _load_rerun()
        self.run = run
        self.path = options.recording_path(run.out_dir)
        self.spawn = options.spawn
        self.connect = options.connect
        self.save = options.save
        self.rec: rr.RecordingStream | None = None
        self.visuals = {arm.name: robot_meshes.link_visuals(arm.urdf) for arm in run.cell.arms}
        self._status: dict[str, list[str]] = {}
        self._now = (0, 0.0)  # (setpoint, sim_time) of the latest event, for events without a time
        #: a viewer streams the run live (else only a file is written, and rows can wait)
        self.live = self.spawn or self.connect is not None
        #: arm transforms not sent yet: entity path -> [(setpoints, times, translations, quaternions)]
        self._arm_rows: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]] = {}

    # ------------------------------------------------------------------ stream
    def open(self) -> rr.RecordingStream | None:
        """Create the run's recording stream and attach its sinks (file and/or viewer); None
        when there is nowhere to send it (a stream without sinks would buffer the whole run in
        memory)."""
        batcher = None
        if not self.live:  # nobody watches live: favour few, large chunks over latency
            batcher = rr.ChunkBatcherConfig(
                flush_tick=timedelta(seconds=FILE_FLUSH_TICK_S), flush_num_bytes=FILE_CHUNK_BYTES
            )
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id(self.run), batcher_config=batcher)
        sinks: list[Any] = []
        if self.save:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(self.path)))
        if self.spawn:
            try:
                # Spawn without connecting, then tee: spawn() alone would replace the file sink.
                rec.spawn(port=SPAWN_PORT, connect=False)
            except Exception as exc:  # a missing viewer or display must not cost the run
                log.warning("could not spawn a Rerun viewer (%s)", exc)
            # A viewer that failed to start (no display) only warns; streaming to its port
            # anyway would stall the end of the run, so check that something listens.
            if _listening(SPAWN_PORT):
                sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{SPAWN_PORT}/proxy"))
            else:
                log.warning(
                    "no Rerun viewer listens on port %d; %s",
                    SPAWN_PORT,
                    "recording to file only" if self.save else "nothing is recorded",
                )
        if self.connect is not None:
            url = urlparse(self.connect)
            if _listening(url.port or 0, url.hostname or "127.0.0.1"):
                sinks.append(rr.GrpcSink(self.connect))
            else:
                log.warning("no Rerun server listens at %s; not streaming there", self.connect)
        if not sinks:
            return None
        from .blueprint import blueprint  # (imports rerun: only once a recording is made)

        rec.set_sinks(*sinks, default_blueprint=blueprint(self.run.cell))
        rec.send_recording_name(Path(self.run.out_dir).name or "agrisim")
        self.rec = rec
        return rec

    def close(self) -> None:
        """Flush and close the stream (idempotent).

        A viewer that went away (closed by the user, or one that could not start) makes Rerun's
        flush raise or wait forever; the file sink is complete by then, so that only warns.
        """
        if self.rec is None:
            return
        self._send_arm_rows()
        rec, self.rec = self.rec, None
        try:
            rec.flush(timeout_sec=FLUSH_TIMEOUT)
        except Exception as exc:
            log.warning("Rerun: not every sink took the whole recording: %s", exc)
        finally:
            rec.disconnect()

    def _set_time(self, setpoint: int, sim_time: float) -> None:
        assert self.rec is not None
        self.rec.set_time(TIMELINE_SETPOINT, sequence=int(setpoint))
        self.rec.set_time(TIMELINE_SIM_TIME, duration=float(sim_time))
        self._now = (int(setpoint), float(sim_time))

    # ------------------------------------------------------------------ static scene
    def _log_obstacle(self, ob: Box | Cylinder) -> None:
        assert self.rec is not None
        from agrisim.robot.cell import Box

        path = paths.obstacle(ob.name)
        T = np.asarray(ob.world_T, float)
        self.rec.log(path, rr.Transform3D(translation=T[:3, 3], quaternion=quaternions_xyzw(T[:3, :3])[0]), static=True)
        color = OBSTACLE_COLORS.get(ob.name, STAND_COLOR)
        # The keep-out zone is virtual: drawn as a wire cage, not as a solid.
        fill = "transparentfillmajorwireframe" if ob.name == "plant_keepout" else "solid"
        if isinstance(ob, Box):
            shape: Any = rr.Boxes3D(
                half_sizes=[np.asarray(ob.size) / 2],
                colors=[color],
                fill_mode=fill,
                labels=[ob.name],
                show_labels=False,
            )
        else:
            shape = rr.Cylinders3D(
                lengths=[ob.height],
                radii=[ob.radius],
                colors=[color],
                fill_mode=fill,
                labels=[ob.name],
                show_labels=False,
            )
        self.rec.log(path, shape, static=True)

    def _log_scene(self, scene: Scene) -> None:
        """The scene's meshes with their albedo textures and vertex colours, and its lights, static."""
        assert self.rec is not None
        for mesh in scene.meshes:
            for mi, material in enumerate(mesh.materials):
                faces = mesh.faces[mesh.face_material == mi]
                if not len(faces):
                    continue
                used, inverse = np.unique(faces, return_inverse=True)
                kwargs: dict[str, Any] = {}
                if material.albedo is not None and mesh.uvs is not None:
                    kwargs["vertex_texcoords"] = mesh.uvs[used]
                    kwargs["albedo_texture"] = np.ascontiguousarray(material.albedo[..., :3])
                else:
                    kwargs["albedo_factor"] = [int(round(255 * c)) for c in material.color[:3]]
                if mesh.colors is not None:  # (Rerun multiplies them with the texture, as glTF does)
                    kwargs["vertex_colors"] = np.round(linear_to_srgb(mesh.colors[used]) * 255).astype(np.uint8)
                self.rec.log(
                    paths.scene_mesh(mesh.name, mi),
                    rr.Mesh3D(
                        vertex_positions=mesh.vertices[used].astype(np.float32),
                        triangle_indices=inverse.reshape(-1, 3).astype(np.uint32),
                        **kwargs,
                    ),
                    static=True,
                )
        if scene.points is not None and scene.points.size is not None:  # a point plant: its spheres
            pts = scene.points
            self.rec.log(
                paths.scene_points(scene.plant),
                rr.Points3D(
                    pts.positions.astype(np.float32),
                    colors=pts.colors,
                    radii=np.full(len(pts), 0.5 * pts.size, np.float32),
                    class_ids=pts.labels,
                ),
                static=True,
            )
        for light in scene.lights:
            origin = np.asarray(light.position, float)
            self.rec.log(
                paths.light(light.name),
                rr.Arrows3D(
                    origins=[origin],
                    vectors=[0.3 * np.asarray(light.direction, float)],
                    colors=[(255, 220, 120)],
                    labels=[light.name],
                ),
                static=True,
            )

    def _log_robot_geometry(self, robot: str) -> None:
        assert self.rec is not None
        for link, visuals in self.visuals[robot].items():
            for v in visuals:
                path = paths.link_visual(robot, link, v.index)
                T = v.link_T_visual
                self.rec.log(
                    path,
                    rr.Transform3D(translation=T[:3, 3], quaternion=quaternions_xyzw(T[:3, :3])[0], scale=v.scale),
                    static=True,
                )
                if v.kind == "mesh" and v.filename:
                    try:
                        contents, media_type = robot_meshes.asset_bytes(v.filename)
                    except Exception as exc:  # a broken visual mesh costs its picture, not the run
                        log.warning("%s/%s: visual mesh %s not recorded: %s", robot, link, v.filename, exc)
                        continue
                    # A URDF material tints the mesh; its own (glTF) colours stay otherwise.
                    albedo = None if v.rgba is None else rgba255(v.rgba, (255, 255, 255, 255))
                    self.rec.log(
                        path, rr.Asset3D(contents=contents, media_type=media_type, albedo_factor=albedo), static=True
                    )
                elif v.kind == "box" and v.size is not None:
                    color = rgba255(v.rgba, PRIMITIVE_COLOR)
                    self.rec.log(
                        path,
                        rr.Boxes3D(half_sizes=[np.asarray(v.size) / 2], colors=[color], fill_mode="solid"),
                        static=True,
                    )
                elif v.kind == "cylinder" and v.radius is not None and v.length is not None:
                    color = rgba255(v.rgba, PRIMITIVE_COLOR)
                    self.rec.log(
                        path,
                        rr.Cylinders3D(lengths=[v.length], radii=[v.radius], colors=[color], fill_mode="solid"),
                        static=True,
                    )
                elif v.kind == "sphere" and v.radius is not None:
                    color = rgba255(v.rgba, PRIMITIVE_COLOR)
                    self.rec.log(
                        path,
                        rr.Ellipsoids3D(half_sizes=[[v.radius] * 3], colors=[color], fill_mode="solid"),
                        static=True,
                    )

    def _log_setpoints(self) -> None:
        assert self.rec is not None
        for robot, sps in self.run.setpoints.items():
            if not sps:
                continue
            T = np.stack([sp.world_T_camera for sp in sps])
            origins = T[:, :3, 3]
            self.rec.log(
                paths.setpoints(robot),
                rr.Points3D(origins, radii=0.008, labels=[sp.frame for sp in sps], show_labels=False),
                static=True,
            )
            self.rec.log(
                paths.setpoint_views(robot),
                rr.Arrows3D(
                    origins=origins,
                    vectors=T[:, :3, 2] * SETPOINT_ARROW,
                    colors=robot_color(self.run, robot),
                    radii=0.002,
                ),
                static=True,
            )
            self._status[robot] = ["pending"] * len(sps)
            self._log_setpoint_status(robot)
            self.rec.log(
                paths.metric(robot, "ee_error_mm"),
                rr.SeriesPoints(colors=[robot_color(self.run, robot)], names=[robot]),
                static=True,
            )

    def _log_setpoint_status(self, robot: str) -> None:
        assert self.rec is not None
        colors = [STATUS_COLORS[s] for s in self._status[robot]]
        # Colours only, at the current time: positions stay static, status changes over time.
        self.rec.log(paths.setpoints(robot), rr.Points3D.from_fields(colors=colors))

    def _link_columns(self, robot: str, qs: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """``entity path -> (translations, quaternions)`` for every visual link and the camera."""
        kin = self.run.kinematics[robot]
        camera_frame = self.run.cell.arm(robot).camera_frame
        wanted = {paths.link(robot, link): link for link in self.visuals[robot]}
        wanted[paths.camera(robot)] = camera_frame
        poses: dict[str, list[np.ndarray]] = {path: [] for path in wanted}
        for q in qs:
            frames = kin.link_poses(q)
            for path, frame in wanted.items():
                if frame in frames:
                    poses[path].append(frames[frame])
        out = {}
        for path, Ts in poses.items():
            if len(Ts) == len(qs) and Ts:
                M = np.stack(Ts)
                out[path] = (M[:, :3, 3], quaternions_xyzw(M[:, :3, :3]))
        return out

    def _log_arm(self, robot: str, setpoint: int | np.ndarray, t: np.ndarray, qs: np.ndarray) -> None:
        """The arm's link and camera transforms at times ``t``: sent at once to a live viewer,
        else held back and sent in chunks of ``ARM_ROWS_PER_CHUNK`` rows per link (one
        ``send_columns`` call is one chunk: per move, that made most of a recording's chunks)."""
        assert self.rec is not None
        t = np.asarray(t, float)
        seq = np.broadcast_to(np.asarray(setpoint, np.int64), t.shape)
        for path, (translation, quaternion) in self._link_columns(robot, qs).items():
            self._arm_rows.setdefault(path, []).append((seq, t, translation, quaternion))
        held = max((sum(len(part[1]) for part in parts) for parts in self._arm_rows.values()), default=0)
        if self.live or held >= ARM_ROWS_PER_CHUNK:
            self._send_arm_rows()

    def _send_arm_rows(self) -> None:
        """Send the held-back arm transforms, one column chunk per link."""
        assert self.rec is not None
        rows, self._arm_rows = self._arm_rows, {}
        for path, parts in rows.items():
            seq, t, translation, quaternion = (np.concatenate([p[i] for p in parts]) for i in range(4))
            self.rec.send_columns(
                path,
                indexes=_time_columns(seq, t),
                columns=rr.Transform3D.columns(translation=translation, quaternion=quaternion),
            )

    # ------------------------------------------------------------------ hooks
    @hookimpl
    def agrisim_run_started(self, run: Run) -> None:
        """Open the stream; log the static cell, the robots at home, setpoints and config."""
        if run is not self.run:
            return
        rec = self.open()
        if rec is None:
            return
        rec.log(paths.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log(paths.RUN_CONFIG, rr.TextDocument(_config_markdown(run), media_type=rr.MediaType.MARKDOWN), static=True)
        for ob in run.cell.obstacles:
            # With a rendered scene its meshes show the cell; only the virtual keep-out stays.
            if run.scene is None or ob.name == "plant_keepout":
                self._log_obstacle(ob)
        if run.scene is not None:
            self._log_scene(run.scene)
        if run.labels is not None:
            self.log_label_table({lab.id: (lab.name, lab.color) for lab in run.labels.labels})
        if run.scene is not None and run.cell.bench:  # each plant's pixels selectable by its name
            context = rr.AnnotationContext([(k + 1, p.name) for k, p in enumerate(run.cell.bench)])
            for arm in run.cell.arms:
                rec.log(paths.camera_image(arm.name, paths.PLANTS), context, static=True)
        for arm in run.cell.arms:
            self._log_robot_geometry(arm.name)
        self._set_time(0, 0.0)
        self._log_setpoints()
        for arm in run.cell.arms:
            self._log_arm(arm.name, 0, np.array([0.0]), np.array([arm.home], float))

    @hookimpl
    def agrisim_trajectory(self, run: Run, robot: str, trajectory: Trajectory) -> None:
        """The arm's links along the executed motion; the camera's planned and executed paths."""
        if run is not self.run or self.rec is None:
            return
        ex = trajectory.executed
        if len(ex.t):
            idx = decimate(ex.t, TRANSFORM_RATE)
            self._log_arm(robot, trajectory.setpoint, np.asarray(ex.t)[idx], np.asarray(ex.q)[idx])
        kin = run.kinematics[robot]
        color = robot_color(run, robot)
        planned = trajectory.planned
        if len(planned.t):
            pts = np.array([kin.fk(q)[:3, 3] for q in np.asarray(planned.q)[decimate(planned.t, PATH_RATE)]])
            self._set_time(trajectory.setpoint, float(planned.t[0]))
            self.rec.log(paths.planned(robot), rr.LineStrips3D([pts], colors=[(*color, 110)], radii=0.002))
        if len(ex.t):
            pts = np.array([kin.fk(q)[:3, 3] for q in np.asarray(ex.q)[decimate(ex.t, PATH_RATE)]])
            self._set_time(trajectory.setpoint, float(ex.t[-1]))
            self.rec.log(paths.executed(robot), rr.LineStrips3D([pts], colors=[color], radii=0.003))

    @hookimpl
    def agrisim_setpoint(self, run: Run, robot: str, result: SetpointResult) -> None:
        """The camera error as a scalar series; reached/failed as a log line and point colour."""
        if run is not self.run or self.rec is None:
            return
        self._set_time(result.index, result.sim_time)
        if result.ee_error_mm is not None:
            self.rec.log(paths.metric(robot, "ee_error_mm"), rr.Scalars(float(result.ee_error_mm)))
        if robot in self._status and 0 <= result.index < len(self._status[robot]):
            self._status[robot][result.index] = "reached" if result.reached else "failed"
            self._log_setpoint_status(robot)
        error = f"{result.ee_error_mm:.4f} mm" if result.ee_error_mm is not None else "no error measured"
        if result.reached:
            self.rec.log(paths.log(robot), rr.TextLog(f"{result.frame}: reached ({error})", level="INFO"))
        else:
            self.rec.log(
                paths.log(robot), rr.TextLog(f"{result.frame}: not reached ({error}): {result.reason}", level="WARN")
            )

    @hookimpl
    def agrisim_capture(self, run: Run, capture: Capture) -> None:
        """The camera pose and intrinsics at the capture; its images when a renderer made any."""
        if run is not self.run or self.rec is None:
            return
        rec = self.rec
        self._set_time(capture.setpoint, capture.sim_time)
        T = np.asarray(capture.world_T_camera, float)
        cam = capture.camera
        rec.log(
            paths.camera(capture.robot), rr.Transform3D(translation=T[:3, 3], quaternion=quaternions_xyzw(T[:3, :3])[0])
        )
        rec.log(
            paths.camera(capture.robot),
            rr.Pinhole(
                image_from_camera=cam.K,
                resolution=[cam.width, cam.height],
                camera_xyz=rr.ViewCoordinates.RDF,
                image_plane_distance=IMAGE_PLANE_DISTANCE,
            ),
        )
        if capture.images is not None:
            self.log_images(capture.robot, capture.images)

    def log_images(self, robot: str, images: Frame) -> None:
        """Log a capture's ``rgb``, ``labels``, ``depth``, leaf ``instances`` and a bench's
        ``plants`` at the current time."""
        assert self.rec is not None
        image = rr.Image(images.rgb)
        # JPEG keeps a full run's frames in tens of MB instead of GB; Pillow is optional.
        if images.rgb.dtype == np.uint8 and importlib.util.find_spec("PIL") is not None:
            image = image.compress(jpeg_quality=RGB_JPEG_QUALITY)
        self.rec.log(paths.camera_image(robot, "rgb"), image)
        self.rec.log(paths.camera_image(robot, "labels"), rr.SegmentationImage(images.labels))
        if images.instances is not None:
            # leaf instance ids (uint16, 0 = none): no annotation context, Rerun colours each id
            self.rec.log(paths.camera_image(robot, "instances"), rr.SegmentationImage(images.instances))
        if images.plants is not None:  # a bench's: which plant (0 none), named by the annotation context
            self.rec.log(paths.camera_image(robot, paths.PLANTS), rr.SegmentationImage(images.plants))
        # Millimetres in uint16 (as the dataset's depth PNGs): half the size of float32 metres
        # and far more compressible; 1 mm steps are invisible at the cell's scale. With a depth
        # sensor, ``depth`` is what it measured (as a robot's camera would publish it) and the
        # exact depth is ``depth_truth``.
        if images.depth_sensor is None:
            self.rec.log(paths.camera_image(robot, "depth"), rr.DepthImage(images.depth_mm(), meter=1000.0))
        else:
            sensed = depth_to_mm(images.depth_sensor)
            self.rec.log(paths.camera_image(robot, "depth"), rr.DepthImage(sensed, meter=1000.0))
            self.rec.log(paths.camera_image(robot, paths.DEPTH_TRUTH), rr.DepthImage(images.depth_mm(), meter=1000.0))

    def log_label_table(self, table: Mapping[int, tuple[str, Sequence[int]]]) -> None:
        """The label ids' names and colours (``id -> (name, rgb)``) for every camera's
        ``labels`` image, static. Call once the plant's label table is known."""
        if self.rec is None:
            return
        context = rr.AnnotationContext([(int(i), name, tuple(color)) for i, (name, color) in sorted(table.items())])
        for robot in self.run.cell.arm_names:
            self.rec.log(paths.camera_image(robot, "labels"), context, static=True)

    @hookimpl
    def agrisim_cloud(self, run: Run, label: str, cloud: Any, merged: bool) -> None:
        """A per-view or merged point cloud, at the time of the latest event."""
        if run is not self.run or self.rec is None:
            return
        points, colors = _cloud_arrays(cloud)
        if points is None:
            log.debug("cloud %r of type %s not recorded", label, type(cloud).__name__)
            return
        cap = MERGED_CLOUD_POINTS if merged else VIEW_CLOUD_POINTS
        if len(points) > cap:
            # an even, repeatable subset: a run's clouds would otherwise outweigh its images
            keep = np.sort(np.random.default_rng(0).choice(len(points), cap, replace=False))
            points, colors = points[keep], (colors[keep] if colors is not None else None)
        self._set_time(*self._now)
        self.rec.log(paths.cloud(label, merged), rr.Points3D(points, colors=colors, radii=rr.Radius.ui_points(1.5)))

    @hookimpl
    def agrisim_run_finished(self, run: Run, summary: RunSummary) -> None:
        """Log the summary, then flush and close the stream."""
        if run is not self.run or self.rec is None:
            return
        try:
            self.rec.log(
                paths.RUN_SUMMARY,
                rr.TextDocument(_summary_markdown(summary), media_type=rr.MediaType.MARKDOWN),
                static=True,
            )
        finally:
            self.close()


def _cloud_arrays(cloud: Any) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Points (N x 3) and optional colours from an array (N x 3 or N x 6) or an object with
    ``points``/``colors`` (Open3D's ``PointCloud``, trimesh's ``PointCloud``)."""
    if isinstance(cloud, np.ndarray):
        if cloud.ndim == 2 and cloud.shape[1] in (3, 6):
            return cloud[:, :3], (cloud[:, 3:6] if cloud.shape[1] == 6 else None)
        return None, None
    points = getattr(cloud, "points", None) if cloud is not None else None
    if points is None:
        return None, None
    pts = np.asarray(points, float)
    colors = getattr(cloud, "colors", None)
    cols = np.asarray(colors) if colors is not None and len(colors) else None
    if cols is not None and cols.shape[0] != pts.shape[0]:
        cols = None
    return pts, cols


def _config_markdown(run: Run) -> str:
    config = json.dumps(run.config.model_dump(mode="json"), indent=2)
    backends = ", ".join(f"{k}: `{v}`" for k, v in run.backends.items())
    return f"# agrisim run\n\nstarted {run.started_at}, backends {backends}\n\n```json\n{config}\n```\n"


def _summary_markdown(summary: RunSummary) -> str:
    rows = "\n".join(f"| {k} | {v} |" for k, v in summary.to_dict().items() if k != "wall_s")
    wall = "\n".join(f"| {k} | {v:.3f} |" for k, v in summary.wall_s.items())
    text = f"# Run summary\n\n| | |\n|---|---|\n{rows}\n"
    if wall:
        text += f"\n## Wall time per stage (s)\n\n| stage | s |\n|---|---|\n{wall}\n"
    return text
