"""A third-party exporter, the way its author ships it: the ``yolo`` exporter of the test package
``tests/e2e/agrisim-yolo-export`` (YOLO detection and segmentation labels), installed as a
distribution into a temporary folder on ``sys.path`` (its module, a dist-info with its own
entry points), found through the ``agrisim`` entry points like the built-in exporters, listed by
``agrisim plugins``, run by ``agrisim export yolo RUN OUT`` and held to the exporter contract.

Its labels are checked against the run's own label and instance PNGs, by other means than the
exporter's: the regions and their boxes from OpenCV's connected components, each polygon
rasterised by OpenCV and compared with its region, holes filled by SciPy. Bad input to
``agrisim export`` exits 2 with one line and changes nothing.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from conftest import installed
from PIL import Image
from scipy import ndimage

from agrisim.registry import Registry, make_plugin_manager
from agrisim.testing.contracts import check

PACKAGE = Path(__file__).resolve().parent / "agrisim-yolo-export"


@pytest.fixture(scope="module")
def run_dir(saved_runs) -> Path:  # noqa: ANN001
    """Hydrangea with organ labels and leaf instances, the arms in view (the session's: the
    exports here go to folders of their own)."""
    return saved_runs.get(plant="hydrangea", render={"labels": "organs"}, recon={"backend": "none"})


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[str, str]]:
    """The package installed as pip lays it out, in a fresh folder on ``sys.path``; its module
    is forgotten afterwards. Yields (distribution name, version)."""
    with installed(PACKAGE, tmp_path / "site", monkeypatch) as dist:
        yield dist


def png(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path))


def snapshot(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() if p.is_file() else b"" for p in sorted(root.rglob("*"))}


def truth(run_dir: Path, frame: str) -> list[tuple[int, np.ndarray, tuple[int, int, int, int]]]:
    """(label id, mask, box x, y, w, h) of every object of ``frame`` by OpenCV: the 8-connected
    components of the pixels sharing a label and a leaf instance."""
    labels = png(run_dir / "labels" / f"{frame}.png")
    path = run_dir / "instances" / f"{frame}.png"
    instances = png(path) if path.is_file() else np.zeros(labels.shape, np.uint16)
    out = []
    for label in np.unique(labels[labels != 0]):
        for instance in np.unique(instances[labels == label]):
            group = ((labels == label) & (instances == instance)).astype(np.uint8)
            n, components, stats, _ = cv2.connectedComponentsWithStats(group, connectivity=8)
            out += [(int(label), components == k, tuple(int(v) for v in stats[k, :4])) for k in range(1, n)]
    return out


def collinear(mask: np.ndarray) -> bool:
    """Do the region's pixel centres lie on one line (no polygon encloses them)?"""
    rows, cols = np.nonzero(mask)
    pts = np.stack([cols, rows], 1).astype(float)
    return bool(np.linalg.matrix_rank(pts - pts.mean(0), tol=1e-9) < 2)


def read_dataset(out: Path, run_dir: Path) -> tuple[dict[int, int], dict[str, list[list[float]]]]:
    """(YOLO class -> the run's label id, frame -> its label lines as numbers), read back;
    data.yaml by PyYAML."""
    data = yaml.safe_load((out / "data.yaml").read_text())
    assert data["train"] == data["val"] == "images" and Path(data["path"]) == out.absolute()
    ids = {row["name"]: row["id"] for row in json.loads((run_dir / "run.json").read_text())["labels"]}
    assert sorted(data["names"]) == list(range(len(ids) - 1))  # every label but background, from 0
    classes = {cls: ids[name] for cls, name in data["names"].items()}
    assert sorted(classes.values()) == sorted(i for i in ids.values() if i != 0)
    lines = {
        p.stem: [[float(v) for v in line.split()] for line in p.read_text().splitlines()]
        for p in sorted((out / "labels").glob("*.txt"))
    }
    return classes, lines


def test_the_exporter_is_listed_with_its_distribution_and_options(site, cli) -> None:  # noqa: ANN001
    dist, version = site
    code, out, err = cli(["plugins", "--options"])
    assert code == 0, err
    section = out[out.index("\nexporter:\n") :].splitlines()
    rows = {line.split()[0]: line for line in section[2:] if line.startswith("  ") and not line.startswith("   ")}
    assert rows["yolo"].endswith(f"[{dist} {version}]") and "YOLO labels" in rows["yolo"]
    assert all("[agrisim " in rows[name] for name in ("coco", "nerfstudio", "rosbag"))  # beside the built-ins
    assert any(line.strip().startswith("exporter.yolo.task = 'segment'") for line in section)


def test_the_exporter_keeps_the_exporter_contract(site) -> None:  # noqa: ANN001
    check("exporter", "yolo", Registry(make_plugin_manager()))


def test_polygons_are_the_runs_regions(site, run_dir: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "yolo"
    code, stdout, err = cli(["export", "yolo", str(run_dir), str(out)])
    assert code == 0 and err == "", err
    assert stdout == f"wrote {out}\n"
    classes, lines = read_dataset(out, run_dir)
    frames = sorted(json.loads((run_dir / "run.json").read_text())["frames_complete"])
    assert sorted(lines) == frames == sorted(p.stem for p in (out / "images").iterdir())
    polygons = 0
    for frame in frames:
        assert (out / "images" / f"{frame}.png").read_bytes() == (run_dir / "rgb" / f"{frame}.png").read_bytes()
        height, width = png(run_dir / "labels" / f"{frame}.png").shape
        expected = Counter(
            (label, ndimage.binary_fill_holes(mask).tobytes())  # YOLO's polygons have no holes
            for label, mask, _ in truth(run_dir, frame)
            if not collinear(mask)
        )
        exported: Counter[tuple[int, bytes]] = Counter()
        for row in lines[frame]:
            assert len(row) >= 7 and len(row) % 2 == 1 and all(0 <= v <= 1 for v in row[1:])
            points = np.rint(np.reshape(row[1:], (-1, 2)) * [width, height]).astype(np.int32)
            mask = np.zeros((height, width), np.uint8)
            cv2.fillPoly(mask, [points], 1)
            exported[(classes[int(row[0])], mask.astype(bool).tobytes())] += 1
        assert exported == expected, frame
        polygons += len(lines[frame])
    assert polygons > 30


def test_boxes_are_the_runs_regions(site, run_dir: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "boxes"
    code, _, err = cli(["export", "yolo", str(run_dir), str(out), "--set", "exporter.yolo.task=detect"])
    assert code == 0, err
    classes, lines = read_dataset(out, run_dir)
    boxes = 0
    for frame, rows in lines.items():
        height, width = png(run_dir / "labels" / f"{frame}.png").shape
        expected = Counter((label, box) for label, _, box in truth(run_dir, frame))
        exported: Counter[tuple[int, tuple[int, ...]]] = Counter()
        for cls, cx, cy, w, h in rows:
            x0, y0 = (cx - w / 2) * width, (cy - h / 2) * height
            exported[(classes[int(cls)], tuple(int(round(v)) for v in (x0, y0, w * width, h * height)))] += 1
        assert exported == expected, frame
        boxes += len(rows)
    assert boxes > 30 and len({row[0] for rows in lines.values() for row in rows}) > 1


def test_refusals_exit_2_with_one_line_and_change_nothing(site, run_dir: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "yolo"
    assert cli(["export", "yolo", str(run_dir), str(out)])[0] == 0
    (tmp_path / "empty").mkdir()
    before = snapshot(tmp_path)
    cases = [
        (["export", "yolo", str(run_dir), str(out)], ["already exists", "--overwrite"]),
        (["export", "yolo", str(run_dir), str(out), "--overwrite", "--set", "exporter.yolo.task=boxes"], ["task"]),
        (["export", "yolo", str(run_dir), str(out), "--overwrite", "--set", "task=detect"], ["exporter.yolo.KEY"]),
        (["export", "yolo", str(tmp_path / "empty"), str(tmp_path / "other")], ["holds no run.json"]),
        (["export", "nosuch", str(run_dir)], ["invalid choice", "'nosuch'", "coco, nerfstudio, rosbag, yolo"]),
    ]
    for args, words in cases:
        code, stdout, err = cli(args)
        assert code == 2 and stdout == "" and err.startswith("agrisim: error: ") and err.count("\n") == 1, err
        assert all(word in err for word in words), err
        assert snapshot(tmp_path) == before, args
    # --overwrite replaces it, and only with a complete export
    code, _, err = cli(["export", "yolo", str(run_dir), str(out), "--overwrite", "--set", "exporter.yolo.task=detect"])
    assert code == 0, err
    assert all(
        len(row) == 5 for p in (out / "labels").glob("*.txt") for row in map(str.split, p.read_text().splitlines())
    )
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging left


def test_an_unknown_exporter_names_the_installed_ones(run_dir: Path, cli) -> None:  # noqa: ANN001
    before = snapshot(run_dir)
    code, stdout, err = cli(["export", "yolo", str(run_dir)])  # not installed here
    assert code == 2 and stdout == "" and err.count("\n") == 1, err
    assert "invalid choice: 'yolo' (choose from coco, nerfstudio, rosbag)" in err
    assert snapshot(run_dir) == before
