"""The ``dataset`` sink: the run's files on disk (DESIGN.md's output layout).

``run.json`` is rewritten atomically after every setpoint, so at any moment it tells how far the
run got (``status`` running / complete / failed / interrupted) and what each setpoint did.
``cameras.json`` holds the intrinsics and the camera pose of every captured frame. Rendered
frames go to ``rgb/``, ``labels/`` (uint8 ids), ``labels_vis/`` (label colours), ``depth/``
(uint16 millimetres, 0 = no hit) and ``instances/`` (uint16 leaf ids), each PNG written
atomically; a frame is listed in ``run.json`` only once all its files exist.
"""

from __future__ import annotations

import io
import platform
import sys
from dataclasses import asdict
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from agrisim import BackendSpec, __version__, hookimpl
from agrisim.assets import export_glb
from agrisim.atomic import write_bytes, write_json
from agrisim.episode import Run, RunSummary, SetpointResult
from agrisim.interfaces import Capture

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


def depth_to_mm(depth: np.ndarray) -> np.ndarray:
    """Metres (float, 0 = no hit) to uint16 millimetres, rounded; beyond 65.535 m saturates."""
    mm = np.rint(np.asarray(depth, np.float64) * 1000.0)
    return np.clip(mm, 0, 65535).astype(np.uint16)


def write_png(path: Path, image: np.ndarray) -> None:
    """A PNG of a uint8 (grey or RGB) or uint16 (grey) image, written atomically."""
    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image)).save(buffer, format="PNG", compress_level=1)
    write_bytes(path, buffer.getvalue())


def _result_row(r: SetpointResult) -> dict[str, Any]:
    row = asdict(r)
    for key in ("ee_error_mm", "rot_error_rad", "ik_s", "plan_s", "motion_s", "sim_time"):
        if row[key] is not None:
            row[key] = round(float(row[key]), 9 if key in ("ee_error_mm", "rot_error_rad") else 6)
    return row


class DatasetSink:
    """Writes ``run.json`` and ``cameras.json`` under the run's output directory."""

    def __init__(self, run: Run) -> None:
        self.out = run.out_dir
        self.frames: dict[str, dict[str, Any]] = {}
        self.status = "running"
        self.summary: dict[str, Any] | None = None

    def _run_json(self, run: Run) -> dict[str, Any]:
        return {
            "agrisim": __version__,
            "status": self.status,
            "started_at": run.started_at,
            "command": sys.argv,
            "seed": run.seed,
            "backends": run.backends,
            "backend_options": run.backend_options,
            "config": run.config.model_dump(mode="json"),
            "versions": package_versions(),
            "labels": [
                {"id": lab.id, "name": lab.name, "color": list(lab.color)} for lab in run.labels.labels
            ]
            if run.labels is not None
            else None,
            "setpoints_planned": {robot: len(sps) for robot, sps in run.setpoints.items()},
            "frames_complete": sorted(self.frames),
            "results": [_result_row(r) for r in run.results],
            "summary": self.summary,
        }

    def _write(self, run: Run) -> None:
        write_json(self.out / "run.json", self._run_json(run))

    @hookimpl
    def agrisim_run_started(self, run: Run) -> None:
        if run.scene is not None and run.labels is not None:
            # the ground truth: the plant as placed in the world, with albedo and labels
            export_glb(run.scene.mesh(run.scene.plant), self.out / "scene" / "plant.glb", run.labels)
        self._write(run)

    @hookimpl
    def agrisim_setpoint(self, run: Run, robot: str, result: SetpointResult) -> None:
        self._write(run)

    def _write_images(self, run: Run, capture: Capture) -> None:
        images = capture.images
        name = f"{capture.frame}.png"
        if "rgb" in images:
            write_png(self.out / "rgb" / name, images["rgb"])
        if "labels" in images:
            write_png(self.out / "labels" / name, images["labels"])
            palette = run.labels.palette() if run.labels is not None else None
            if palette is not None:
                write_png(self.out / "labels_vis" / name, palette[images["labels"]])
        if "depth" in images:
            write_png(self.out / "depth" / name, depth_to_mm(images["depth"]))
        if images.get("instances") is not None:
            write_png(self.out / "instances" / name, images["instances"].astype(np.uint16))

    @hookimpl
    def agrisim_capture(self, run: Run, capture: Capture) -> None:
        self._write_images(run, capture)
        self.frames[capture.frame] = {
            "robot": capture.robot,
            "setpoint": capture.setpoint,
            "sim_time": round(capture.sim_time, 6),
            "world_T_camera": np.round(capture.world_T_camera, 12).tolist(),
        }
        cam = capture.camera
        write_json(
            self.out / "cameras.json",
            {
                "convention": "OpenCV (x right, y down, z forward); pixel centres at integer coordinates",
                "intrinsics": {
                    "width": cam.width,
                    "height": cam.height,
                    "K": cam.K.tolist(),
                    "hfov_deg": cam.hfov_deg,
                },
                "frames": dict(sorted(self.frames.items())),
            },
        )

    @hookimpl
    def agrisim_run_finished(self, run: Run, summary: RunSummary) -> None:
        self.status = summary.status
        self.summary = summary.to_dict()
        self._write(run)


@hookimpl
def agrisim_sinks() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="dataset",
            factory=DatasetSink,
            description="run.json (config, versions, per-setpoint results, summary) and cameras.json under --out",
        )
    ]
