"""A run through a lens given as ROS's ``camera_info`` (``--camera-calibration``): what it writes
carries the lens, and what reads it back reads it through the lens.

* ``cameras.json`` holds the calibration's K and coefficients; OpenCV's own YAML and JSON of the
  same calibration give the same camera;
* the plant's cloud is exact: precision@1mm 1.0 with exact depth (measured; the same views
  back-projected as through a pinhole give 0.69, the break this guards against);
* ``transforms.json`` names ``OPENCV`` with the coefficients, and the rays that OpenCV's
  ``undistortPoints`` makes of them through nerfstudio's pixel centres meet the true plant at
  the exported depth.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import small_run
from test_exports import _doc, _first_plant_hit, _image, _plant_mesh

from agrisim.scene.calibration import read_calibration

K = np.array([[150.0, 0.0, 159.5], [0.0, 150.0, 89.5], [0.0, 0.0, 1.0]])
D = np.array([-0.25, 0.06, 0.001, -0.001, -0.005])  # strong barrel: 10% at the corners
CAMERA_INFO = f"""\
image_width: 320
image_height: 180
camera_name: agrisim_test
camera_matrix:
  rows: 3
  cols: 3
  data: [{", ".join(map(str, K.ravel()))}]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [{", ".join(map(str, D))}]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
"""


@pytest.fixture(scope="module")
def calibration(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("calibration") / "camera_info.yaml"
    path.write_text(CAMERA_INFO)
    return path


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory, calibration: Path) -> Path:
    out = tmp_path_factory.mktemp("lens") / "run"
    return small_run(out, camera={"resolution": None, "calibration": str(calibration)})


@pytest.mark.parametrize("suffix", [".yml", ".json"])
def test_opencvs_files_give_the_camera_ros_gives(calibration: Path, tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"calibration{suffix}"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)  # as OpenCV's calibration sample writes it
    fs.write("image_width", 320)
    fs.write("image_height", 180)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", D.reshape(1, 5))
    fs.release()
    assert read_calibration(path) == read_calibration(calibration)


def test_the_run_writes_and_reads_its_lens(run_dir: Path) -> None:
    intrinsics = json.loads((run_dir / "cameras.json").read_text())["intrinsics"]
    np.testing.assert_array_equal(intrinsics["K"], K)
    lens = intrinsics["distortion"]
    assert lens["model"] == "brown-conrady"
    np.testing.assert_array_equal([lens[k] for k in ("k1", "k2", "p1", "p2", "k3")], D)
    precision = json.loads((run_dir / "metrics.json").read_text())["labels"]["plant"]["precision"]
    assert precision["1"] > 0.99, precision


def test_nerfstudios_rays_through_the_lens_meet_the_plant(run_dir: Path) -> None:
    doc = _doc(run_dir)
    assert doc["camera_model"] == "OPENCV"
    coefficients = np.array([doc[k] for k in ("k1", "k2", "p1", "p2", "k3")])
    np.testing.assert_array_equal(coefficients, D)
    # nerfstudio's pixel centres are at +0.5: pixel (col, row) is the point (col + 0.5, row + 0.5)
    Kn = np.array([[doc["fl_x"], 0, doc["cx"]], [0, doc["fl_y"], doc["cy"]], [0, 0, 1]])
    rows, cols = np.mgrid[0 : doc["h"], 0 : doc["w"]]
    centres = np.stack([cols + 0.5, rows + 0.5], -1).reshape(-1, 1, 2).astype(np.float64)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15)
    slopes = cv2.undistortPoints(centres, Kn, coefficients, criteria=criteria)[:, 0, :]
    local = np.column_stack([slopes[:, 0], -slopes[:, 1], -np.ones(len(slopes))])  # OpenGL: y up, looking -z
    mesh = _plant_mesh(run_dir)
    for frame in doc["frames"]:
        c2w = np.array(frame["transform_matrix"])
        dirs = local @ c2w[:3, :3].T
        t = _first_plant_hit(mesh, np.broadcast_to(c2w[:3, 3], dirs.shape).copy(), dirs)  # = planar depth
        depth = _image(run_dir, frame["depth_file_path"]).ravel() * doc["depth_unit_scale_factor"]
        plant = _image(run_dir, frame["mask_path"]).ravel() > 0
        agree = plant & (np.abs(t - depth) <= 0.0005 + 1e-6)  # the PNG rounds to whole millimetres
        assert plant.sum() > 1000
        assert agree.sum() >= 0.99 * plant.sum(), f"{frame['file_path']}: {agree.sum()}/{plant.sum()}"


def test_the_bags_camera_info_carries_the_lens(run_dir: Path, cli) -> None:  # noqa: ANN001
    """``agrisim export rosbag``: every ``camera_info`` read back by mcap_ros2 (ROS 2's reader)
    says ``plumb_bob`` with the calibration's coefficients, the ones ``image_raw`` was taken
    through."""
    from test_rosbag import read_bag

    code, _, err = cli(["export", "rosbag", str(run_dir)])
    assert code == 0, err
    infos = [msg for topic, msgs in read_bag(run_dir).items() if topic.endswith("camera_info") for _, msg in msgs]
    assert len(infos) == 6
    for info in infos:
        assert info.distortion_model == "plumb_bob"
        np.testing.assert_array_equal(info.d, D)
        np.testing.assert_array_equal(np.reshape(info.k, (3, 3)), K)
