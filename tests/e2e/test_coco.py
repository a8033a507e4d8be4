"""``agrisim export coco``: the annotations read back by pycocotools (the library COCO users
load them with), every decoded mask against the run's label and instance PNGs, the regions'
connectivity against scikit-image's labelling, and the refusals (exit 2, one line, nothing
written or replaced)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from pycocotools.coco import COCO
from skimage.measure import label as connected

from agrisim.plugins.exporters.coco import COCO_JSON


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory, saved_runs) -> Path:  # noqa: ANN001
    """Hydrangea with organ labels and leaf instances, the arms in view (a copy of the
    session's: the exports are written into it)."""
    out = tmp_path_factory.mktemp("coco") / "run"
    return saved_runs.copy(out, plant="hydrangea", render={"labels": "organs"}, recon={"backend": "none"})


def png(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path))


def test_masks_read_back_by_pycocotools_are_the_runs_own(run_dir: Path, cli) -> None:  # noqa: ANN001
    code, out, _ = cli(["export", "coco", str(run_dir)])
    assert code == 0 and "annotations.json" in out
    coco = COCO(str(run_dir / COCO_JSON))
    table = {r["id"]: r["name"] for r in json.loads((run_dir / "run.json").read_text())["labels"] if r["id"]}
    assert {c["id"]: c["name"] for c in coco.loadCats(coco.getCatIds())} == table
    frames = json.loads((run_dir / "run.json").read_text())["frames_complete"]
    assert sorted(img["file_name"] for img in coco.dataset["images"]) == sorted(f"rgb/{f}.png" for f in frames)
    leaf = next(i for i, n in table.items() if n == "leaf")
    checked_instances = 0
    for img in coco.dataset["images"]:
        frame = Path(img["file_name"]).stem
        labels = png(run_dir / "labels" / f"{frame}.png")
        instances = png(run_dir / "instances" / f"{frame}.png")
        anns = coco.loadAnns(coco.getAnnIds(imgIds=[img["id"]]))
        covered = np.zeros(labels.shape, int)
        for ann in anns:
            mask = coco.annToMask(ann).astype(bool)
            assert mask.any() and ann["iscrowd"] == 0
            assert ann["area"] == mask.sum()
            rows, cols = np.nonzero(mask)
            assert ann["bbox"] == [cols.min(), rows.min(), cols.max() - cols.min() + 1, rows.max() - rows.min() + 1]
            covered += mask
            ids = np.unique(instances[mask])
            if ids.tolist() != [0]:  # a leaf instance: exactly its pixels
                assert len(ids) == 1 and ann["category_id"] == leaf
                assert np.array_equal(mask, (instances == ids[0]) & (labels != 0))
                checked_instances += 1
            else:  # one 8-connected region of one label
                assert np.all(labels[mask] == ann["category_id"])
                assert connected(mask, connectivity=2).max() == 1
        assert covered.max() <= 1  # disjoint
        assert np.array_equal(covered == 1, labels != 0)  # every labelled pixel, the arms none
        # as many regions per label as scikit-image finds among the pixels without an instance
        rest = (labels != 0) & (instances == 0)
        for lab in np.unique(labels[rest]):
            n = connected(rest & (labels == lab), connectivity=2).max()
            assert n == sum(
                1 for a in anns if a["category_id"] == lab and not np.any(instances[coco.annToMask(a).astype(bool)])
            )
    assert checked_instances > 10


def test_refusals_write_nothing(run_dir: Path, cli, tmp_path: Path) -> None:  # noqa: ANN001
    target = run_dir / COCO_JSON
    if not target.exists():
        assert cli(["export", "coco", str(run_dir)])[0] == 0
    before = target.read_bytes()
    code, _, err = cli(["export", "coco", str(run_dir)])
    assert code == 2 and "--overwrite" in err and len(err.strip().splitlines()) == 1
    assert target.read_bytes() == before
    assert cli(["export", "coco", str(run_dir), "--overwrite"])[0] == 0
    # a run that is not complete
    broken = tmp_path / "broken"
    broken.mkdir()
    doc = json.loads((run_dir / "run.json").read_text())
    (broken / "run.json").write_text(json.dumps(dict(doc, status="running")))
    (broken / "cameras.json").write_text((run_dir / "cameras.json").read_text())
    code, _, err = cli(["export", "coco", str(broken)])
    assert code == 2 and "not complete" in err and not (broken / "coco").exists()
