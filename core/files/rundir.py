"""The run directory from outside the writer: reading it back (its JSON documents, checked,
with one-line errors), and checking and preparing the output directory of a new or resumed run.

``run.json`` and ``cameras.json`` are agrisim's own files, but a directory given on the command
line may be anything: every reader here turns a missing, unreadable or malformed document into
a :class:`agrisim.errors.UserError` (or the subclass the caller names) that says which file and
why.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import shutil
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.interfaces import CameraModel
from agrisim.scene.lens import Distortion

if TYPE_CHECKING:
    from agrisim.config import RunConfig


def read_json(path: Path, missing: str, error: type[UserError] = UserError, prefix: str = "") -> dict[str, Any]:
    """The JSON object in ``path``. A missing file is reported as ``<dir> holds no <name>:
    <missing>``; an unreadable or non-object one names the file. ``prefix`` starts every
    message (``"--resume: "``)."""
    if not path.is_file():
        raise error(f"{prefix}{path.parent} holds no {path.name}: {missing}")
    try:
        doc = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise error(f"{prefix}cannot read {path}: {exc}") from None
    if not isinstance(doc, dict):
        raise error(f"{prefix}{path} is not a JSON object")
    return doc


def read_run(run_dir: Path, rendered: bool = True) -> tuple[dict[str, Any], dict[str, Any]]:
    """``run.json`` and ``cameras.json`` of a *complete* run, checked; a run that is still
    running, was interrupted or failed is refused (its frames are not all there), and so is a
    run without rendered frames unless ``rendered`` is False."""
    if not run_dir.is_dir():
        raise UserError(f"{run_dir} is not a directory")
    run, cameras = (
        read_json(run_dir / name, "not a rendered agrisim run" if rendered else "not an agrisim run")
        for name in (layout.RUN_JSON, layout.CAMERAS_JSON)
    )
    status = run.get("status")
    if status != "complete":
        raise UserError(
            f"the run in {run_dir} is {status or 'of unknown status'}, not complete: "
            f"finish it first with agrisim run --resume --out {run_dir}"
        )
    if rendered and not isinstance(run.get("labels"), list):
        raise UserError(f"the run in {run_dir} has no rendered frames (was it made with --renderer none?)")
    frames = cameras.get("frames")
    if not isinstance(frames, dict) or not isinstance(cameras.get("intrinsics"), dict):
        raise UserError(f"{run_dir / 'cameras.json'} has no intrinsics and frames")
    complete = run.get("frames_complete") or []
    missing = sorted(set(complete) - set(frames))
    if missing:
        raise UserError(f"{run_dir / 'cameras.json'} lacks frames {', '.join(missing[:3])} that run.json lists")
    for name in complete if isinstance(run.get("labels"), list) else []:  # a robot-only run has no images
        for folder in layout.REQUIRED_FOLDERS:
            if not layout.has_image(run_dir, folder, name):
                raise UserError(
                    f"missing {folder} image {layout.image(run_dir, folder, name)}: the run's frames are incomplete"
                )
    return run, cameras


def camera_from_json(intrinsics: dict[str, Any]) -> CameraModel:
    """The camera of ``cameras.json``'s intrinsics: its pinhole and, when it has one, its lens."""
    K = np.asarray(intrinsics["K"], float)
    lens = intrinsics.get("distortion")
    return CameraModel(
        int(intrinsics["width"]),
        int(intrinsics["height"]),
        K[0, 0],
        K[1, 1],
        K[0, 2],
        K[1, 2],
        None if lens is None else Distortion.from_dict(lens),
    )


def camera_to_json(camera: CameraModel) -> dict[str, Any]:
    """``cameras.json``'s intrinsics of ``camera``: size, ``K``, the horizontal field of view
    and, through a lens, ``distortion`` (OpenCV's model and coefficients by name)."""
    doc: dict[str, Any] = {"width": camera.width, "height": camera.height, "K": camera.K.tolist()}
    doc["hfov_deg"] = camera.hfov_deg
    if camera.distortion is not None:
        doc["distortion"] = camera.distortion.as_dict()
    return doc


# ---------------------------------------------------------------- the output directory of a run


def resolve_out_dir(config: RunConfig) -> Path:
    """The output directory, checked (not created): exists only with --overwrite, writable."""
    out = config.output.out
    if out is None:
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / stamp
    out = out.expanduser()
    if config.output.resume:
        saved_run(out)  # raises unless there is an unfinished run to continue
        return out
    if out.exists():
        if not out.is_dir():
            raise OutputError(f"--out {out} exists and is not a directory")
        if any(out.iterdir()) and not config.output.overwrite:
            raise OutputError(f"--out {out} already exists; pass --overwrite to replace it")
    parent = out
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"--out {out} is not writable ({parent} does not allow creating files)")
    return out


def saved_run(out: Path) -> dict[str, Any]:
    """The ``run.json`` of an unfinished run in ``out`` (for ``--resume``)."""
    path = out / layout.RUN_JSON
    doc = read_json(path, "not an agrisim run to continue", OutputError, prefix="--resume: ")
    if not isinstance(doc.get("config"), dict):
        raise OutputError(f"--resume: {path} holds no run configuration")
    if doc.get("status") == "complete":
        raise OutputError(f"--resume: the run in {out} is complete; nothing to continue")
    return doc


def saved_frames(out: Path) -> dict[str, Any]:
    """The frames ``cameras.json`` in ``out`` lists (frame -> its entry); none when it has no
    such file yet (for ``--resume``)."""
    path = out / layout.CAMERAS_JSON
    if not path.is_file():
        return {}
    frames = read_json(path, "not a camera list", OutputError, prefix="--resume: ").get("frames")
    return frames if isinstance(frames, dict) else {}


def prepare_out_dir(out: Path, config: RunConfig) -> None:
    """Create the output directory, replacing an old one only under --overwrite."""
    if out.exists() and config.output.overwrite:
        shutil.rmtree(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create --out {out}: {exc}") from None


def capture_order(run: dict[str, Any], frames: Iterable[str]) -> list[str]:
    """``frames`` in the order they were captured: as run.json's results list them, then any
    others by name."""
    wanted = set(frames)
    order = [r["frame"] for r in run.get("results", []) if r.get("frame") in wanted]
    return order + sorted(wanted - set(order))
