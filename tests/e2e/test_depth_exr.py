"""``--depth-format``: float depth in OpenEXR beside (or instead of) the millimetre PNGs. Truths:
the PNG's own millimetres, the true plant mesh (Open3D's closest points), and the reconstruction
of the same views replayed from disk (``agrisim recon``), which must be the run's own."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import small_run
from PIL import Image

from agrisim.evaluation.metrics import GroundTruth, SurfaceDistance
from agrisim.evaluation.views import backproject, load_view
from agrisim.files import layout
from agrisim.files.exr import read_exr
from agrisim.files.rundir import camera_from_json, read_run
from agrisim.plugins.formats.plant_asset import load_plant
from agrisim.scene.encoding import depth_to_mm


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("depth")
    return {
        fmt: small_run(root / fmt, plant="hydrangea", render={"depth_format": fmt}, metrics={"truth_samples": 100_000})
        for fmt in ("both", "exr")
    }


def test_exr_is_exact_and_the_png_its_millimetres(runs: dict[str, Path]) -> None:
    run_dir = runs["both"]
    run, cameras = read_run(run_dir)
    camera = camera_from_json(cameras["intrinsics"])
    truth = GroundTruth.sample(load_plant(run_dir / layout.PLANT_GLB, place=False).mesh, 100_000, 0)
    distance = SurfaceDistance(truth)
    exr_d, png_d = [], []
    for frame in run["frames_complete"]:
        depth = read_exr(layout.depth_exr(run_dir, frame))
        png = np.asarray(Image.open(layout.image(run_dir, "depth", frame)))
        assert depth.dtype == np.float32 and depth.shape == png.shape
        assert np.array_equal(depth_to_mm(depth), png)  # the same depth, rounded
        assert np.array_equal(depth == 0, png == 0)  # 0 where nothing was hit
        view = load_view(run_dir, frame, camera, np.asarray(cameras["frames"][frame]["world_T_camera"]))
        assert np.array_equal(view.images.depth, depth)  # readers take the exact depth
        plant = view.images.labels != 0
        exr_d.append(distance(backproject(view, plant, 10.0)[0], None))
        view.images.depth = png.astype(np.float32) / np.float32(1000.0)
        png_d.append(distance(backproject(view, plant, 10.0)[0], None))
    exr_d, png_d = np.concatenate(exr_d), np.concatenate(png_d)
    assert len(exr_d) > 1000
    assert np.percentile(exr_d, 99) < 1e-5  # on the true surface to 10 micrometres
    assert np.percentile(png_d, 90) > 10 * np.percentile(exr_d, 90)  # millimetres are coarser


def test_exr_only_runs_reconstruct_the_same_from_disk(runs: dict[str, Path], cli, tmp_path: Path) -> None:  # noqa: ANN001
    run_dir = runs["exr"]
    assert not list((run_dir / "depth").glob("*.png")) and list((run_dir / "depth").glob("*.exr"))
    code, _, err = cli(["recon", str(run_dir), "--out", str(tmp_path / "re")])
    assert code == 0, err
    for ply in sorted((run_dir / "clouds").glob("*.ply")):
        assert (tmp_path / "re" / "clouds" / ply.name).read_bytes() == ply.read_bytes(), ply.name
    doc = json.loads((run_dir / "transforms.json").read_text())
    assert all("depth_file_path" not in f for f in doc["frames"])  # nerfstudio reads PNG depth only
