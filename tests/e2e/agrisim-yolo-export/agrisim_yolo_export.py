"""``yolo``: a third-party agrisim exporter (a test package): a run's labels as a YOLO dataset,
in the layout Ultralytics reads (``agrisim export yolo RUN_DIR [OUT]``, default
``RUN_DIR/yolo``)::

    OUT/data.yaml              path, train and val (both images), names: class id -> label name
    OUT/images/<frame>.png     the run's rgb/<frame>.png (a hard link, else a copy)
    OUT/labels/<frame>.txt     one line per object, coordinates normalised by the image's size

Classes are the run's labels without background, in id order, numbered from 0. An object is one
8-connected region of the pixels sharing a label and a leaf instance (instance 0: no leaf), so a
leaf that the plant partly hides is as many objects as pieces are seen. A line is, by the
option ``task``:

* ``detect``: ``class cx cy w h``, the region's box over whole pixels;
* ``segment`` (default): ``class x1 y1 x2 y2 ...``, the region's outer boundary as OpenCV traces
  it (``findContours``, external, simple chains: the boundary pixels' centres at integer
  coordinates, divided by the image's width and height, as Ultralytics' own mask converter
  does). Holes are not kept (YOLO's polygons have none), and a region whose pixels lie on one
  line (a pixel, a one-pixel stroke) has no polygon and no line.

The exporter keeps agrisim's contract (:class:`agrisim.interfaces.Exporter`): everything is read
and checked first, bad input is one :class:`agrisim.errors.UserError`, an existing ``OUT`` is
replaced only with ``--overwrite`` (and then only once the new one is complete).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np
from PIL import Image

from agrisim import BackendSpec, Options, hookimpl
from agrisim.errors import OutputError, UserError
from agrisim.files.atomic import staged_dir
from agrisim.files.rundir import read_run
from agrisim.interfaces import Exporter

__version__ = "0.1.0"

#: 8-connectivity (OpenCV's for foreground contours): diagonal neighbours are one region
EIGHT = np.ones((3, 3), bool)


class YoloOptions(Options):
    """Options of the ``yolo`` exporter (``--set exporter.yolo.KEY=VALUE``)."""

    task: Literal["segment", "detect"] = "segment"
    """segment: a polygon per object (its outer boundary); detect: a box per object."""


def _png(path: Path) -> np.ndarray:
    try:
        with Image.open(path) as im:
            return np.asarray(im)
    except (OSError, ValueError) as exc:
        raise UserError(f"cannot read {path}: {exc}") from None


def objects(labels: np.ndarray, instances: np.ndarray | None) -> list[tuple[int, np.ndarray]]:
    """(label id, mask) of every object of one frame: each 8-connected region of the pixels
    sharing a label and a leaf instance."""
    from scipy import ndimage

    key = labels.astype(np.int64) << 16
    if instances is not None:
        key |= instances.astype(np.int64)
    out: list[tuple[int, np.ndarray]] = []
    for k in np.unique(key[labels != 0]):
        regions, n = ndimage.label(key == k, structure=EIGHT)
        out += [(int(k >> 16), regions == i) for i in range(1, n + 1)]
    return out


def box_line(cls: int, mask: np.ndarray) -> str:
    height, width = mask.shape
    rows, cols = np.nonzero(mask)
    x0, x1, y0, y1 = cols.min(), cols.max() + 1, rows.min(), rows.max() + 1
    cx, cy, w, h = (x0 + x1) / 2 / width, (y0 + y1) / 2 / height, (x1 - x0) / width, (y1 - y0) / height
    return f"{cls} {cx:.6f} {cy:.6f} {w:.6f} {h:.6f}"


def polygon_line(cls: int, mask: np.ndarray) -> str | None:
    import cv2

    height, width = mask.shape
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    (contour,) = contours  # one 8-connected region: one outer boundary
    points = contour[:, 0, :]
    if len(points) < 3:  # its pixels lie on one line: no polygon
        return None
    return f"{cls} " + " ".join(f"{x / width:.6f} {y / height:.6f}" for x, y in points)


class YoloExporter(Exporter):
    """``agrisim export yolo RUN_DIR [OUT]``: the YOLO dataset folder OUT (default RUN_DIR/yolo)."""

    default_out = "yolo"
    progress_unit = "frames"

    def export(
        self,
        run_dir: Path,
        out: Path,
        overwrite: bool = False,
        progress: Callable[[int, int], None] | None = None,
    ) -> Path:
        run_dir, out = Path(run_dir), Path(out)
        if out.exists() and not overwrite:
            raise OutputError(f"{out} already exists; pass --overwrite to replace it")
        if out.exists() and not out.is_dir():
            raise OutputError(f"{out} is not a directory; the YOLO export is a folder")
        run, _ = read_run(run_dir)
        frames = sorted(run.get("frames_complete") or [])
        if not frames:
            raise UserError(f"the run in {run_dir} has no rendered frames to label")
        table = sorted((int(row["id"]), str(row["name"])) for row in run["labels"] if int(row["id"]) != 0)
        classes = {label: cls for cls, (label, _) in enumerate(table)}
        line = polygon_line if self.options.task == "segment" else box_line
        texts: dict[str, str] = {}
        for k, frame in enumerate(frames):  # every frame read and labelled before anything is written
            labels = _png(run_dir / "labels" / f"{frame}.png")
            path = run_dir / "instances" / f"{frame}.png"
            instances = _png(path) if path.is_file() else None
            lines = [line(classes[label], mask) for label, mask in objects(labels, instances) if label in classes]
            texts[frame] = "".join(f"{text}\n" for text in lines if text is not None)
            if progress is not None:
                progress(k + 1, len(frames))
        names = "".join(f"  {cls}: {json.dumps(name)}\n" for cls, (_, name) in enumerate(table))  # YAML's too
        with staged_dir(out) as staging:
            (staging / "images").mkdir()
            (staging / "labels").mkdir()
            for frame, text in texts.items():
                (staging / "labels" / f"{frame}.txt").write_text(text)
                image = run_dir / "rgb" / f"{frame}.png"
                try:
                    os.link(image, staging / "images" / image.name)
                except OSError:  # another file system: a copy
                    shutil.copyfile(image, staging / "images" / image.name)
            (staging / "data.yaml").write_text(
                f"path: {json.dumps(str(out.absolute()))}\ntrain: images\nval: images\nnames:\n{names}"
            )
        return out


@hookimpl
def agrisim_exporters() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="yolo",
            factory=YoloExporter,
            options_model=YoloOptions,
            description="YOLO labels (Ultralytics' layout): a polygon or a box per object, one .txt per frame",
        )
    ]
