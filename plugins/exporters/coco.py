"""The ``coco`` exporter: ``RUN_DIR/coco/annotations.json`` (or the ``OUT`` file named) in COCO's
instance format, which pycocotools, Detectron2, MMDetection and Ultralytics' converters read.

- ``images``: one per complete frame, ``file_name`` ``rgb/<frame>.png`` relative to the run
  directory (the image root to give a loader), ``width``, ``height``.
- ``categories``: the run's label table without background: id = label id, name = organ name
  (or ``plant``), supercategory ``plant``.
- ``annotations`` (rule): where the frame has leaf instances, each leaf instance's pixels are
  one annotation whose category is the label most of its pixels carry; every other labelled
  pixel (instance 0) is split into 8-connected regions per label (``scipy.ndimage.label``),
  one annotation each. Masks are exact: the arms and the lab are background. Each has an RLE
  ``segmentation`` (pycocotools' compressed counts), ``area`` (pixels), ``bbox`` [x, y, w, h]
  and ``iscrowd`` 0.
- a bench (``run.json``'s ``bench``): each annotation also carries ``plant``, the id of the
  plant it lies on (``plants/<frame>.png``'s value; a leaf instance lies on one plant, and the
  other labels' regions are split where two plants touch), and the document's ``plants`` names
  them (id, name, what grew it, seed, x, y: :mod:`agrisim.plugins.sinks.dataset.bench`). COCO
  readers (pycocotools) keep extra keys as they are. A run of one plant has neither.

The semantic masks are the run's ``labels/<frame>.png`` themselves (uint8 label ids).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from agrisim import BackendSpec, hookimpl
from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.files.atomic import write_json
from agrisim.files.rundir import read_run
from agrisim.interfaces import Exporter
from agrisim.plugins.sinks.dataset.bench import bench_rows, read_bench

COCO_JSON = Path("coco") / "annotations.json"
#: 8-connectivity: diagonal neighbours belong to one region (thin stems stay whole)
EIGHT = np.ones((3, 3), bool)


def _png(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im)


def frame_regions(
    labels: np.ndarray, instances: np.ndarray | None, plants: np.ndarray | None = None
) -> list[tuple[int, int, np.ndarray]]:
    """(category, plant, mask) of every annotation of one frame, by the module's rule; with a
    bench's ``plants`` image, regions are split where two plants touch and each has its plant's
    id (a leaf instance lies on one plant), else plant 0."""
    from scipy import ndimage

    out: list[tuple[int, int, np.ndarray]] = []
    rest = labels != 0
    owner = np.zeros(labels.shape, np.uint16) if plants is None else plants

    if instances is not None:
        for inst in np.unique(instances[rest]):
            if inst == 0:
                continue
            mask = (instances == inst) & rest
            out.append((int(np.bincount(labels[mask]).argmax()), int(np.bincount(owner[mask]).argmax()), mask))
        rest &= instances == 0
    # each (label, plant) present, as label << 16 | plant, in label order
    for pair in np.unique(labels[rest].astype(np.uint32) << 16 | owner[rest]):
        label, plant = int(pair) >> 16, int(pair) & 0xFFFF
        regions, n = ndimage.label(rest & (labels == label) & (owner == plant), structure=EIGHT)
        out += [(label, plant, regions == k) for k in range(1, n + 1)]
    return out


def coco_document(run_dir: Path) -> dict[str, Any]:
    """The annotations document of a complete run (everything read and checked first)."""
    from pycocotools import mask as rle

    run, cameras = read_run(run_dir)
    frames = sorted(run.get("frames_complete") or [])
    if not frames:
        raise UserError(f"the run in {run_dir} has no rendered frames to annotate (was it made with --renderer none?)")
    width, height = int(cameras["intrinsics"]["width"]), int(cameras["intrinsics"]["height"])
    bench = read_bench(run, run_dir / layout.RUN_JSON)
    lacking = [f for f in frames if bench and not layout.image(run_dir, layout.PLANTS, f).is_file()]
    if lacking:
        raise UserError(
            f"missing {layout.image(run_dir, layout.PLANTS, lacking[0])}: the bench's frames are incomplete"
        )
    categories = [
        {"id": int(r["id"]), "name": r["name"], "supercategory": "plant"} for r in run["labels"] if int(r["id"]) != 0
    ]
    images: list[dict[str, Any]] = []
    annotations: list[dict[str, Any]] = []
    for image_id, frame in enumerate(frames, start=1):
        images.append({"id": image_id, "file_name": f"rgb/{frame}.png", "width": width, "height": height})
        labels = _png(layout.image(run_dir, "labels", frame))
        path = layout.image(run_dir, "instances", frame)
        instances = _png(path) if path.is_file() else None
        plants = _png(layout.image(run_dir, layout.PLANTS, frame)) if bench else None
        for category, plant, mask in frame_regions(labels, instances, plants):
            encoded = rle.encode(np.asfortranarray(mask.astype(np.uint8)))
            annotations.append(
                {
                    "id": len(annotations) + 1,
                    "image_id": image_id,
                    "category_id": category,
                    "segmentation": {"size": encoded["size"], "counts": encoded["counts"].decode("ascii")},
                    "area": int(rle.area(encoded)),
                    "bbox": [float(x) for x in rle.toBbox(encoded)],
                    "iscrowd": 0,
                    **({"plant": plant} if bench else {}),
                }
            )
    doc = {
        "info": {"description": f"agrisim run {run_dir.name}", "version": str(run.get("agrisim_version", ""))},
        "images": images,
        "annotations": annotations,
        "categories": categories,
    }
    if bench:
        doc["plants"] = bench_rows(bench)
    return doc


def write_coco(run_dir: Path, overwrite: bool = False, out: Path | None = None) -> Path:
    """Write ``out`` (default ``run_dir/coco/annotations.json``); an existing one needs
    ``overwrite``. Its images' ``file_name`` stay relative to the run directory."""
    run_dir = Path(run_dir)
    out = run_dir / COCO_JSON if out is None else Path(out)
    if out.exists() and not overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")
    if out.is_dir():
        raise OutputError(f"{out} is a directory; the COCO export is one JSON file (e.g. {out / 'annotations.json'})")
    write_json(out, coco_document(run_dir))
    return out


class CocoExporter(Exporter):
    """``agrisim export coco RUN_DIR [OUT]``: OUT is the annotations file (default
    ``RUN_DIR/coco/annotations.json``)."""

    default_out = COCO_JSON.as_posix()

    def export(
        self,
        run_dir: Path,
        out: Path,
        overwrite: bool = False,
        progress: Callable[[int, int], None] | None = None,
    ) -> Path:
        return write_coco(run_dir, overwrite, out)


@hookimpl
def agrisim_exporters() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="coco",
            factory=CocoExporter,
            description="COCO instance annotations (RUN_DIR/coco/annotations.json): each leaf instance and each "
            "8-connected region of every other label an RLE mask (pycocotools), area and box",
            limits="instance segmentation only (no keypoints, captions or panoptic segments)",
        )
    ]
