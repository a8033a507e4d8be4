"""The RealSense D435 stereo sensor (``plugins/sensors/stereo.py``) against its published
behaviour, on analytic scenes (planes at known depths, a step edge, rods):

* on a plane, the depth's RMS error grows with the square of the distance and lies within a
  factor of 1.5 of Intel's formula, z^2 x subpixel / (f x baseline) with its typical subpixel
  of 0.08, at three distances the D435 covers (measured ratios 0.82-1.23 over seeds and
  0.5-2.8 m);
* beside a step edge, the band the left imager sees and the right one does not (no match: no
  depth) is as wide as the geometry says: the disparity step, f b (1 / z_near - 1 / z_far);
* a rod narrower than the matching window vanishes; a wide one is measured;
* a wall beyond the range, which the dots barely reach, gives no depth: the texture filter
  drops the guesses the matcher makes on its noise (measured: 0.4-0.5% of it kept, against
  6-7.5% without the filter), and the lit plane before it keeps its depth.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import kernels_launched

from agrisim.config import RenderConfig
from agrisim.plugins.sensors.stereo import DEVICES, StereoOptions, StereoSensor
from agrisim.scene.model import LabelTable, Material, Mesh, Scene

D435 = DEVICES["d435"]
HOME = np.eye(4)
#: Intel's typical subpixel accuracy of the D4xx's matching (the RMS formula's)
SUBPIXEL = 0.08


def _quad(x: tuple[float, float], z: float, name: str) -> Mesh:
    v = np.array([[x[0], -20, z], [x[1], -20, z], [x[1], 20, z], [x[0], 20, z]], float)
    return Mesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), [Material(name, nir=0.5)], np.zeros(2))


def _native(*meshes: Mesh, seed: int = 1, device: str = "d435", **options: int) -> tuple[np.ndarray, StereoSensor]:
    scene = Scene(list(meshes), [], LabelTable())
    sensor = StereoSensor(scene, None, RenderConfig(hide_robots=True), StereoOptions(variant="llvm", **options), device)
    return sensor.measure_native(HOME, {}, seed), sensor


def test_rms_error_on_a_plane_follows_intels_formula():
    for z in (0.5, 1.0, 2.0):
        depth, sensor = _native(_quad((-20, 20), z, "plane"))
        error = depth[depth > 0] - z  # the plane faces the imagers: its planar depth is z
        # all but the band on the left no disparity search reaches (Intel's "invalid depth band")
        band = sensor.disparity_range()[1] / sensor.camera.width
        assert (depth > 0).mean() > 0.97 * (1 - band)
        formula = z * z * SUBPIXEL / (sensor.camera.fx * D435.baseline_m)
        assert 1 / 1.5 < error.std() / formula < 1.5, (
            f"{z} m: RMS {1e3 * error.std():.2f} mm, Intel's {1e3 * formula:.2f}"
        )
        assert abs(error.mean()) < 0.02 * z  # the datasheet's absolute accuracy: under 2%


@pytest.mark.parametrize("near", [0.6, 0.45])
def test_the_occlusion_band_beside_a_step_has_its_geometric_width(near: float):
    far = 1.0
    # the near plane covers x > 0: the background just left of its edge is hidden from the
    # right imager (1 baseline to the right)
    depth, sensor = _native(_quad((0, 20), near, "near"), _quad((-20, 20), far, "far"))
    cam = sensor.camera
    u0 = int(round(cam.cx))
    missing = (depth[60:-60, u0 - 60 : u0 + 60] == 0).sum(axis=1)
    band = cam.fx * D435.baseline_m * (1 / near - 1 / far)
    assert abs(np.median(missing) - band) < 2.0, f"band {np.median(missing)} px, geometry {band:.1f} px"


def test_a_rod_thinner_than_the_matching_window_vanishes():
    z, behind = 0.8, 1.5

    def measured(width: float) -> tuple[float, int]:
        depth, sensor = _native(_quad((-width / 2, width / 2), z, "rod"), _quad((-20, 20), behind, "wall"))
        cam = sensor.camera
        columns = np.abs((np.arange(cam.width) - cam.cx) / cam.fx * z) < width / 2
        on = depth[60:-60][:, columns]
        return float((np.abs(on - z) < 0.03).mean()), int(columns.sum())

    thin, px = measured(0.008)
    assert px < StereoOptions().block_size and thin < 0.05, (thin, px)
    wide, px = measured(0.04)
    assert px > 3 * StereoOptions().block_size and wide > 0.6, (wide, px)


def test_the_texture_filter_drops_matches_on_noise():
    near, wall = 0.6, 8.0  # the wall: beyond the range, 180 times dimmer in the dots than the plane

    def measured(**options: int) -> tuple[float, float]:
        depth, sensor = _native(_quad((0, 20), near, "near"), _quad((-40, 40), wall, "wall"), **options)
        u0 = int(round(sensor.camera.cx))
        return float((depth[:, : u0 - 60] > 0).mean()), float((np.abs(depth[:, u0 + 10 :] - near) < 0.02).mean())

    kept, plane = measured()
    unfiltered, _ = measured(texture_count=0)
    assert kept < 0.015 and kept < unfiltered / 4, (kept, unfiltered)
    assert plane > 0.98


def test_the_nearest_depth_follows_the_image_size():
    """The datasheet's minimum (the D415's 0.45 m) is at 1280 x 720; at 848 x 480 the ASIC's 126
    disparities reach 0.30 m: a plane at 0.35 m is measured, one at 0.26 m is not."""
    inside, _ = _native(_quad((-20, 20), 0.35, "plane"), device="d415")
    assert (np.abs(inside - 0.35) < 0.01).mean() > 0.8
    beyond, _ = _native(_quad((-20, 20), 0.26, "plane"), device="d415")
    assert (np.abs(beyond - 0.26) < 0.01).mean() < 0.05


def test_every_pose_reuses_the_first_views_kernels():
    """The projector's dots drawn from other poses launch the first pose's kernels again,
    compiling none: the pose is data, not code (as literals, every view compiled its own)."""
    _, sensor = _native(_quad((0, 20), 0.6, "near"), _quad((-20, 20), 1.2, "far"))
    poses = []
    for k in (1, 2, 3):
        T, turn = np.eye(4), np.radians(2.0 * k)  # moved, and turned about the optical axis
        T[:2, :2] = [[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]]
        T[:3, 3] = (0.01 * k, -0.02 * k, 0.005 * k)
        poses.append(T)
    first = kernels_launched(lambda: sensor.measure_native(poses[0], {}, 1))
    for T in poses[1:]:
        again = kernels_launched(lambda T=T: sensor.measure_native(T, {}, 1))
        assert again and {k.hash for k in again} <= {k.hash for k in first}
        assert not any(k.fresh for k in again)
