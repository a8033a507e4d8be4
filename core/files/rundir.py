"""Reading a run directory back: its JSON documents, checked, with one-line errors.

``run.json`` and ``cameras.json`` are agrisim's own files, but a directory given on the command
line may be anything: every reader here turns a missing, unreadable or malformed document into
a :class:`agrisim.errors.UserError` (or the subclass the caller names) that says which file and
why.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.files import layout
from agrisim.errors import UserError
from agrisim.interfaces import CameraModel
from agrisim.scene.model import Label, LabelTable


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


def read_run(run_dir: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """``run.json`` and ``cameras.json`` of a *complete* run, checked; a run that is still
    running, was interrupted or failed is refused (its frames are not all there)."""
    if not run_dir.is_dir():
        raise UserError(f"{run_dir} is not a directory")
    run, cameras = (read_json(run_dir / name, "not a rendered agrisim run") for name in (layout.RUN_JSON, layout.CAMERAS_JSON))
    status = run.get("status")
    if status != "complete":
        raise UserError(
            f"the run in {run_dir} is {status or 'of unknown status'}, not complete: "
            f"finish it first with agrisim run --resume --out {run_dir}"
        )
    if not isinstance(run.get("labels"), list):
        raise UserError(f"the run in {run_dir} has no label table (was it rendered?)")
    frames = cameras.get("frames")
    if not isinstance(frames, dict) or not isinstance(cameras.get("intrinsics"), dict):
        raise UserError(f"{run_dir / 'cameras.json'} has no intrinsics and frames")
    complete = run.get("frames_complete") or []
    missing = sorted(set(complete) - set(frames))
    if missing:
        raise UserError(f"{run_dir / 'cameras.json'} lacks frames {', '.join(missing[:3])} that run.json lists")
    for name in complete:
        for folder in layout.REQUIRED_FOLDERS:
            if not layout.image(run_dir, folder, name).is_file():
                raise UserError(f"missing {folder} image {layout.image(run_dir, folder, name)}: the run's frames are incomplete")
    return run, cameras


def camera_from_json(intrinsics: dict[str, Any]) -> CameraModel:
    """The pinhole of ``cameras.json``'s intrinsics."""
    K = np.asarray(intrinsics["K"], float)
    return CameraModel(int(intrinsics["width"]), int(intrinsics["height"]), K[0, 0], K[1, 1], K[0, 2], K[1, 2])


def label_table_from_json(rows: list[dict[str, Any]]) -> LabelTable:
    """The label table ``run.json`` records."""
    return LabelTable([Label(int(r["id"]), str(r["name"]), tuple(int(c) for c in r["color"])) for r in rows])
