"""The run directory's writer: the run's files on disk (DESIGN.md's output layout).

Core code, always on, not a plugin: ``--resume``, ``agrisim recon``, the exports and
``agrisim compare`` read what it writes. A run that rendered frames ends with the exports it
writes itself (nerfstudio's ``transforms.json``: :data:`agrisim.files.exports.RUN_EXPORTS`),
through the exporters installed. The episode registers it for every run before any
sink plugin; it observes the run through the same event hooks.

``run.json`` is rewritten atomically after every setpoint, so at any moment it tells how far the
run got (``status`` running / complete / failed / interrupted) and what each setpoint did; a
bench's run.json names its plants (``bench``: :mod:`agrisim.plugins.sinks.dataset.bench`).
``cameras.json`` holds the intrinsics and the camera pose of every captured frame;
``trajectories/`` every move of an arm (planned and executed joints in simulated time, what the
ROS 2 bag export publishes as joint states and TF), rendered or not. Rendered
frames go to ``rgb/``, ``labels/`` (uint8 ids), ``labels_vis/`` (label colours), ``depth/``
(uint16 millimetres, 0 = no hit), ``instances/`` (uint16 leaf ids), ``plants/`` (a bench's: uint16, which plant) and, with a depth sensor
other than the exact one, ``depth_sensor/`` (what it measured, aligned to the camera's pixels,
uint16 millimetres, 0 = no measurement; its imager and pose in ``cameras.json``), each PNG written
atomically; a frame is listed in ``run.json`` only once all its files exist. A complete run's
reconstruction goes to ``clouds/`` and its accuracy to ``metrics.json`` before ``run.json``
says ``complete``.
"""

from __future__ import annotations

import platform
import sys
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import fields
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.files import layout
from agrisim.files.atomic import to_json, write_bytes, write_json
from agrisim.files.exr import write_exr
from agrisim.files.png import encode_png
from agrisim.files.rundir import camera_to_json
from agrisim.interfaces import CameraModel, Capture, Frame, JointTrajectory, Trajectory
from agrisim.plugins.sinks.dataset import bench, json_text
from agrisim.plugins.sinks.dataset.glb import export_glb
from agrisim.plugins.sinks.dataset.plants import (
    PLANTS_KEY,
    evaluate_plants,
    run_reconstructor,
    write_plants,
)
from agrisim.plugins.sinks.dataset.point_cloud import write_points_ply
from agrisim.plugins.sinks.dataset.reconstruction import write_reconstruction
from agrisim.plugins.sinks.dataset.scene_glb import write_scene
from agrisim.records import Run, RunSummary, SetpointResult
from agrisim.registry import hookimpl
from agrisim.scene.encoding import depth_to_mm
from agrisim.version import __version__

#: distributions whose versions a run records
VERSIONED = (
    "agrisim",
    "numpy",
    "pin",
    "coal",
    "example-robot-data",
    "pybullet",
    "ompl",
    "ruckig",
    "rerun-sdk",
    "open3d",
    "trimesh",
    "pydantic",
    "pluggy",
)


def package_versions() -> dict[str, str]:
    """Installed versions of the libraries a run depends on (absent ones are omitted)."""
    out = {"python": platform.python_version()}
    for name in VERSIONED:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def write_png(path: Path, image: np.ndarray, palette: np.ndarray | None = None) -> None:
    """A PNG of a uint8 (grey or RGB) or uint16 (grey) image, written atomically; with a
    ``palette`` (256 x 3 uint8) a uint8 image is written as an indexed-colour PNG."""
    write_bytes(path, encode_png(image, palette))


def _write_pretty(path: Path, doc: dict[str, Any]) -> None:
    """``doc`` as pretty JSON (the bytes :func:`~agrisim.files.atomic.write_json` writes),
    atomically, its :class:`~agrisim.plugins.sinks.dataset.json_text.Spliced` members spliced in."""
    write_bytes(path, (json_text.dumps(doc, default=to_json) + "\n").encode())


def _result_row(r: SetpointResult) -> dict[str, Any]:
    # asdict's deep copy, for this flat record (it is built for every row at every setpoint)
    row = {f.name: getattr(r, f.name) for f in fields(r)}
    row["contacts"] = list(r.contacts)
    for key in ("ee_error_mm", "rot_error_rad", "ik_s", "plan_s", "motion_s", "sim_time"):
        if row[key] is not None:
            row[key] = round(float(row[key]), 9 if key in ("ee_error_mm", "rot_error_rad") else 6)
    return row


class DatasetWriter:
    """Writes the run's files under its output directory.

    Images are encoded and written by one background thread (PNG encoding releases the GIL),
    so the next frame renders meanwhile. A frame enters ``cameras.json`` and ``run.json``'s
    ``frames_complete`` only once all its files are on disk.
    """

    def __init__(self, run: Run, options: object = None) -> None:
        self.out = run.out_dir
        self.options = options
        #: what writes the exports the run makes itself (:data:`agrisim.files.exports.RUN_EXPORTS`)
        #: into the run directory it is given, once run.json is final
        self.exports = tuple(run.exports)
        self.frames: dict[str, dict[str, Any]] = {}
        self.status = "running"
        self.summary: dict[str, Any] | None = None
        self.camera: CameraModel | None = None
        self.sensor = None if run.sensor is None else (run.backends.get("sensor", ""), run.sensor)
        self.imager = run.imager
        self.versions = package_versions()  # once: run.json is rewritten after every setpoint
        self._writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="agrisim-dataset")
        self._pending: list[tuple[Future[None], str, dict[str, Any]]] = []
        self._moves: list[Future[None]] = []  # trajectory files being written
        self._scene_written: Future[None] | None = None
        # run.json's results and cameras.json's frames grow with every setpoint and are
        # rewritten each time: their members' text is encoded once (json_text)
        self._result_texts = json_text.MemberCache(to_json)
        self._frame_texts = json_text.MemberCache(to_json)

    def _run_json(self, run: Run) -> dict[str, Any]:
        doc: dict[str, Any] = {
            "agrisim": __version__,
            "status": self.status,
            "started_at": run.started_at,
            "command": sys.argv,
            "seed": run.seed,
            "backends": run.backends,
            "backend_options": run.backend_options,
            "config": run.config.model_dump(mode="json"),
            "plant_notes": run.plant_notes,
            "versions": self.versions,
            "labels": run.labels.to_json() if run.labels is not None else None,
            "setpoints_planned": {robot: len(sps) for robot, sps in run.setpoints.items()},
            "frames_complete": sorted(self.frames),
            "results": self._result_texts.array([_result_row(r) for r in run.results]),
            "summary": self.summary,
        }
        # the plants, for readers that do not grow them again (a run of one has none), each with
        # its faces of scene/plant.glb where the run drew them
        drawn = run.scene.bench if run.scene is not None else []
        if drawn or run.cell.bench:
            doc[bench.KEY] = bench.bench_rows(drawn or run.cell.bench, faces=bool(drawn))
        return doc

    def _collect(self, wait: bool = False) -> bool:
        """Move frames whose files are written into the index; True if any moved."""
        for future in [f for f in self._moves if wait or f.done()]:
            future.result()  # a failed write fails the run here, not silently
            self._moves.remove(future)
        moved = False
        still = []
        for future, frame, entry in self._pending:
            if wait or future.done():
                future.result()  # a failed write fails the run here, not silently
                self.frames[frame] = entry
                moved = True
            else:
                still.append((future, frame, entry))
        self._pending = still
        if moved:
            self._write_cameras()
        return moved

    def _write_cameras(self) -> None:
        cam = self.camera
        if cam is None:
            return
        _write_pretty(
            self.out / layout.CAMERAS_JSON,
            {
                "convention": "OpenCV (x right, y down, z forward); pixel centres at integer coordinates",
                "intrinsics": camera_to_json(cam),
                **({"sensor": self._sensor_doc()} if self.sensor is not None else {}),
                **({"imager": self.imager} if self.imager is not None else {}),
                "frames": self._frame_texts.object(dict(sorted(self.frames.items()))),
            },
        )

    def _sensor_doc(self) -> dict[str, Any]:
        """The depth sensor's imager and pose against the camera (what ``depth_sensor/`` was
        measured with, then aligned to the camera's pixels)."""
        assert self.sensor is not None
        name, geometry = self.sensor
        sc = geometry.camera
        return {
            "name": name,
            "intrinsics": camera_to_json(sc),
            "camera_T_sensor": np.asarray(geometry.camera_T_sensor, np.float64).tolist(),
            "depth": f"{layout.DEPTH_SENSOR}/: uint16 mm, planar, on the camera's pixels (aligned), 0 = no measurement",
        }

    def _write(self, run: Run) -> None:
        self._collect()
        _write_pretty(self.out / layout.RUN_JSON, self._run_json(run))

    @hookimpl
    def agrisim_run_started(self, run: Run) -> None:
        if run.scene is not None and run.labels is not None:
            # the ground truth: the plant's surface as placed in the world, with albedo and labels
            surface = run.scene.plant_surface()
            if surface is not None:
                export_glb(surface, self.out / layout.PLANT_GLB, run.labels)
            if run.scene.points is not None:  # the plant as drawn: its points
                write_points_ply(self.out / layout.PLANT_POINTS, run.scene.points, run.labels)
            # the whole scene as drawn, for agrisim render (arms shown at home in viewers):
            # encoding its textures takes most of a second, so the writer thread does it while
            # the robot starts moving
            home = {
                a.name: run.kinematics[a.name].link_poses(np.asarray(a.home))
                for a in run.cell.arms
                if a.name in run.kinematics
            }
            self._scene_written = self._writer.submit(write_scene, self.out / layout.SCENE_GLB, run.scene, home)
        self._write(run)

    @hookimpl
    def agrisim_trajectory(self, run: Run, robot: str, trajectory: Trajectory) -> None:
        frame = next(sp.frame for sp in run.setpoints[robot] if sp.index == trajectory.setpoint)
        doc = trajectory_document(trajectory, frame, run.cell.arm(robot).joints)
        self._moves.append(self._writer.submit(write_json, layout.trajectory(self.out, frame), doc, True))

    @hookimpl
    def agrisim_setpoint(self, run: Run, robot: str, result: SetpointResult) -> None:
        self._write(run)

    @hookimpl
    def agrisim_capture(self, run: Run, capture: Capture) -> None:
        self.camera = capture.camera
        palette = run.labels.palette() if run.labels is not None else None
        entry = {
            "robot": capture.robot,
            "setpoint": capture.setpoint,
            "sim_time": float(capture.sim_time),  # full precision: the bag export stamps by it
            # full precision: a re-render (agrisim render) must see the very pose rendered
            "world_T_camera": np.asarray(capture.world_T_camera, np.float64).tolist(),
        }
        if capture.exposure is not None:  # the imager's: what --resume's auto-exposure goes on from
            entry["exposure"] = capture.exposure
        if capture.replayed:  # complete on disk from before --resume: nothing to write again
            self.frames[capture.frame] = entry
            self._write_cameras()
            return
        future = self._writer.submit(
            write_frame,
            self.out,
            capture.frame,
            capture.images,
            palette,
            capture.link_poses,
            run.config.render.depth_format,
        )
        self._pending.append((future, capture.frame, entry))
        self._collect()

    def _plants(self, run: Run) -> dict[str, Any]:
        """Each plant of the run's bench reconstructed and measured alone, from the frames on
        disk as ``agrisim recon`` replays them (:func:`~.plants.evaluate_plants`)."""
        from agrisim.registry import Registry, make_plugin_manager

        assert run.scene is not None and run.labels is not None and self.camera is not None
        registry = Registry(make_plugin_manager())
        return evaluate_plants(
            self.out,
            run.scene.bench,
            run_reconstructor(registry, run.config, run.labels),
            run.labels,
            {"results": [{"frame": r.frame} for r in run.results]},
            {"intrinsics": camera_to_json(self.camera), "frames": self.frames},
            run.config.metrics.thresholds_mm,
            run.config.metrics.truth_samples,
            registry,
            depth=run.config.recon.depth,
        )

    @hookimpl
    def agrisim_run_finished(self, run: Run, summary: RunSummary) -> None:
        try:
            self._collect(wait=True)
            if self._scene_written is not None:
                self._scene_written.result()  # a failed write fails the run here, not silently
            if run.reconstruction is not None and run.metrics is not None:
                if run.scene is not None and run.scene.bench:
                    run.metrics[PLANTS_KEY] = write_plants(self.out, self._plants(run))
                write_reconstruction(self.out, run.reconstruction, run.metrics)
        finally:
            self._writer.shutdown(wait=True)
            self.status = summary.status
            self.summary = summary.to_dict()
            _write_pretty(self.out / layout.RUN_JSON, self._run_json(run))
        if self.frames and run.labels is not None:
            # after run.json: the exports read the frames it lists as complete
            for export in self.exports:
                export(self.out)


def _joint_trajectory(jt: JointTrajectory) -> dict[str, Any]:
    return {"t": jt.t.tolist(), "q": jt.q.tolist(), "qd": jt.qd.tolist() if jt.qd is not None else None}


def trajectory_document(trajectory: Trajectory, frame: str, joints: tuple[str, ...]) -> dict[str, Any]:
    """``trajectories/<frame>.json``: one arm's move, full precision (a resumed run rewrites
    it with the very same bytes). ``t`` in simulated seconds since the run started, ``q`` in
    radians (one row per time, columns in ``joints`` order), ``qd`` in rad/s or null where the
    physics reports no velocities."""
    return {
        "robot": trajectory.robot,
        "setpoint": trajectory.setpoint,
        "frame": frame,
        "joints": list(joints),
        "path": np.asarray(trajectory.path, float).tolist(),
        "planned": _joint_trajectory(trajectory.planned),
        "executed": _joint_trajectory(trajectory.executed),
    }


def write_frame(
    out: Path,
    frame: str,
    images: Frame | None,
    palette: np.ndarray | None,
    link_poses: dict[str, dict[str, np.ndarray]] | None = None,
    depth_format: str = "png16",
) -> None:
    """One frame's files (rgb, labels, labels_vis, depth as ``depth_format`` says, instances,
    the radiance when kept, and the arms' link poses it was rendered with), each atomic; none
    when the run has no renderer.
    The link poses and radiance come first: a frame whose images exist has them."""
    if images is None:
        return
    if link_poses is not None:
        write_json(
            layout.link_poses(out, frame),
            {r: {k: np.asarray(T).tolist() for k, T in links.items()} for r, links in link_poses.items()},
        )
    if images.radiance is not None:
        write_exr(layout.radiance(out, frame), images.radiance)
    write_png(layout.image(out, "rgb", frame), images.rgb)
    write_png(layout.image(out, "labels", frame), images.labels)
    if palette is not None:
        write_png(layout.image(out, "labels_vis", frame), images.labels, palette=palette)
    if depth_format in ("exr", "both"):
        write_exr(layout.depth_exr(out, frame), np.asarray(images.depth, np.float32))
    if depth_format in ("png16", "both"):
        write_png(layout.image(out, "depth", frame), images.depth_mm())
    if images.instances is not None:
        write_png(layout.image(out, "instances", frame), images.instances.astype(np.uint16))
    if images.plants is not None:
        write_png(layout.image(out, layout.PLANTS, frame), images.plants.astype(np.uint16))
    if images.depth_sensor is not None:
        write_png(layout.image(out, layout.DEPTH_SENSOR, frame), depth_to_mm(images.depth_sensor))
    if images.raw is not None:
        write_png(layout.image(out, layout.RAW, frame), images.raw)
