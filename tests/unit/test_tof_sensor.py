"""The Azure Kinect time-of-flight sensor (``plugins/sensors/tof.py``) against its published
behaviour, on analytic scenes (planes of known reflectance at known distances, a step edge):

* on a plane, the random error stays within Microsoft's published bound (17 mm) at the worst
  reflectance the bound is given for, grows in proportion to the distance (shot noise), and the
  systematic error stays under 11 mm + 0.1% of the distance;
* surfaces too dark or too far give no depth, and too bright and near ones saturate;
* a depth edge gives flying pixels between the two surfaces, and the filter removes them;
* the depth lands on the colour camera's pixels where the geometry puts it (the alignment).
"""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.config import RenderConfig
from agrisim.plugins.sensors import tof
from agrisim.plugins.sensors.tof import AzureKinectOptions, AzureKinectSensor
from agrisim.scene.camera import from_fov
from agrisim.scene.model import LabelTable, Material, Mesh, Scene

#: the colour camera, at the world origin looking down +z (OpenCV axes = world axes)
COLOUR = from_fov(90.0, 320, 240)
HOME = np.eye(4)


def _quad(x: tuple[float, float], z: float, nir: float, name: str) -> Mesh:
    v = np.array([[x[0], -20, z], [x[1], -20, z], [x[1], 20, z], [x[0], 20, z]], float)
    return Mesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), [Material(name, nir=nir)], np.zeros(2))


def _sensor(*meshes: Mesh, **options: object) -> AzureKinectSensor:
    scene = Scene(list(meshes), [], LabelTable())
    return AzureKinectSensor(scene, None, RenderConfig(hide_robots=True), AzureKinectOptions(variant="llvm", **options))


def _world_z(sensor: AzureKinectSensor, native: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(world z, x, range) of the valid pixels of the sensor's own image."""
    cam, T = sensor.camera, HOME @ sensor.camera_T_sensor
    v, u = np.nonzero(native > 0)
    z = native[v, u].astype(np.float64)
    p = np.column_stack([(u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z])
    return (p @ T[:3, :3].T + T[:3, 3])[:, 2], (p @ T[:3, :3].T + T[:3, 3])[:, 0], np.linalg.norm(p, axis=1)


def test_random_error_on_a_plane_is_within_the_published_bounds_and_grows_with_distance():
    spread = {}
    for d in (0.8, 1.6, 3.0):  # inside the NFOV operating range, 0.5-3.86 m
        sensor = _sensor(_quad((-20, 20), d, tof.WORST_REFLECTANCE, "plane"))
        depth = sensor.measure(COLOUR, HOME, {}, None)  # type: ignore[arg-type]
        error = depth[depth > 0] - d  # the plane faces the colour camera: its planar depth is d
        assert (depth > 0).mean() > 0.4  # the sensor's view covers much of the colour camera's
        assert error.std() <= tof.RANDOM_ERROR_M, f"{d} m: {1e3 * error.std():.1f} mm random error"
        assert abs(error.mean()) < 0.011 + 0.001 * d, f"{d} m: {1e3 * error.mean():.1f} mm systematic"
        spread[d] = error.std()
        sensor.close()
    # shot noise: the error of a surface of fixed reflectance grows as its distance
    for d in (1.6, 3.0):
        assert spread[d] / spread[0.8] == pytest.approx(d / 0.8, rel=0.12), spread


def test_without_noise_the_plane_is_exact_on_every_colour_pixel_the_sensor_sees():
    d = 1.2
    sensor = _sensor(_quad((-20, 20), d, 0.5, "plane"), noise=0.0)
    depth = sensor.measure(COLOUR, HOME, {}, None)  # type: ignore[arg-type]
    np.testing.assert_allclose(depth[depth > 0], d, atol=2e-4)
    # Independent: which colour pixels the sensor's imager sees, by projecting each one's point
    # on the plane into the sensor (pixel centres at integer coordinates, the image's edges half
    # a pixel out); one pixel of slack at the border, where footprints are cut.
    v, u = np.mgrid[0 : COLOUR.height, 0 : COLOUR.width]
    p = np.stack([(u - COLOUR.cx) / COLOUR.fx * d, (v - COLOUR.cy) / COLOUR.fy * d, np.full(u.shape, d)], -1)
    S = np.linalg.inv(sensor.camera_T_sensor)
    q = p @ S[:3, :3].T + S[:3, 3]
    cam = sensor.camera
    su, sv = q[..., 0] / q[..., 2] * cam.fx + cam.cx, q[..., 1] / q[..., 2] * cam.fy + cam.cy
    inside = (su > 0.5) & (su < cam.width - 1.5) & (sv > 0.5) & (sv < cam.height - 1.5)
    outside = (su < -1.5) | (su > cam.width + 0.5) | (sv < -1.5) | (sv > cam.height + 0.5)
    assert (depth[inside] > 0).all(), f"{(depth[inside] == 0).sum()} colour pixels in the sensor's view got no depth"
    assert (depth[outside] == 0).all(), "depth outside the sensor's field of view"
    assert inside.mean() > 0.4


def test_too_dark_and_far_is_invalid_too_bright_and_near_saturates():
    dark = _sensor(_quad((-20, 20), 3.8, 0.03, "plane"))
    assert (dark.measure_native(HOME, {}, 1) > 0).mean() < 0.01
    bright = _sensor(_quad((-20, 20), 1.0, 0.5, "plane"))
    assert (bright.measure_native(HOME, {}, 1) > 0).mean() > 0.999
    # a white card 20 cm in front: its middle, face on, saturates (its rim, farther and at a
    # slant, returns less)
    near = _sensor(_quad((-20, 20), 0.2, 0.95, "plane")).measure_native(HOME, {}, 1)
    assert not near[tof.HEIGHT // 2 - 64 : tof.HEIGHT // 2 + 64, tof.WIDTH // 2 - 64 : tof.WIDTH // 2 + 64].any()


def test_a_depth_edge_gives_flying_pixels_and_the_filter_removes_them():
    near, far = 1.0, 1.3  # a step 0.3 m deep, the near half x < 0
    meshes = (_quad((-20, 0), near, 0.5, "near"), _quad((-20, 20), far, 0.5, "far"))
    # six of the model's standard deviations from either surface (at its dimmest, the corners)
    margin = 6 * float(tof.random_error(0.5, 1.6 * far, cosine=0.8))
    counts = {}
    for filtered in (False, True):
        sensor = _sensor(*meshes, flying_pixel_filter=filtered)
        native = sensor.measure_native(HOME, {}, 7)
        z, x, _ = _world_z(sensor, native)
        flying = (z > near + margin) & (z < far - margin)
        counts[filtered] = int(flying.sum())
        if not filtered:
            # they lie along the edge, between the two surfaces
            assert np.abs(x[flying] / z[flying]).max() < 0.02
        else:
            assert (native > 0).mean() > 0.99  # the filter takes little else
    assert counts[False] > 100, counts  # each pixel on the edge mixes both surfaces
    assert counts[True] == 0, counts


def test_alignment_keeps_the_nearest_of_overlapping_footprints():
    """Across depth edges, footprints of several sensor pixels cover one colour pixel: it takes
    the nearest, as a z-buffer does (against a pixel-by-pixel reference)."""
    from agrisim.plugins.sensors.align import align_to_colour
    from agrisim.scene.camera import CameraModel

    sensor = CameraModel(40, 30, 30.0, 30.0, 19.5, 14.5)
    colour = CameraModel(64, 48, 40.0, 40.0, 31.5, 23.5)
    T = np.eye(4)
    T[:3, 3] = (0.05, -0.02, 0.01)
    rng = np.random.default_rng(3)
    depth = rng.choice([0.0, 0.4, 0.7, 1.3], size=(30, 40)).astype(np.float32)
    got = align_to_colour(depth, sensor, colour, T)
    want = np.full((48, 64), np.inf)
    for v, u in zip(*np.nonzero(depth), strict=True):
        z = float(depth[v, u])
        corners = []
        for du, dv in ((-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)):
            p = np.array([(u + du - sensor.cx) / sensor.fx * z, (v + dv - sensor.cy) / sensor.fy * z, z])
            q = T[:3, :3] @ p + T[:3, 3]
            corners.append((q[0] / q[2] * colour.fx + colour.cx, q[1] / q[2] * colour.fy + colour.cy))
        xs, ys = zip(*corners, strict=True)
        centre = T[:3, :3] @ np.array([(u - sensor.cx) / sensor.fx * z, (v - sensor.cy) / sensor.fy * z, z]) + T[:3, 3]
        for y in range(int(np.ceil(min(ys))), int(np.floor(max(ys))) + 1):
            for x in range(int(np.ceil(min(xs))), int(np.floor(max(xs))) + 1):
                if 0 <= x < 64 and 0 <= y < 48:
                    want[y, x] = min(want[y, x], centre[2])
    want[~np.isfinite(want)] = 0.0
    np.testing.assert_allclose(got, want.astype(np.float32), rtol=1e-6)
    assert (got > 0).mean() > 0.3  # (the colour camera sees wider than the sensor)


def test_the_kernels_mix_the_returns_as_the_reference_does():
    """The returns summed on Dr.Jit (what a view measures) equal numpy's :func:`tof.mix` of the
    same returns, across a depth edge where they mix."""
    sensor = _sensor(_quad((-20, 0), 1.0, 0.5, "near"), _quad((-20, 20), 1.3, 0.5, "far"))
    world_T_sensor = HOME @ sensor.camera_T_sensor
    ranges, amplitudes, _ = sensor.returns(world_T_sensor)
    want_range, want_amplitude = tof.mix(ranges, amplitudes)
    got_range, got_amplitude, _ = sensor.mixed(world_T_sensor)
    seen = want_amplitude > 0
    np.testing.assert_allclose(got_range[seen], want_range[seen], atol=1e-5)
    np.testing.assert_allclose(got_amplitude[seen], want_amplitude[seen], rtol=1e-4)
    straddling = (ranges.max(axis=0) - ranges.min(axis=0) > 0.2) & (amplitudes > 0).all(axis=0)
    assert straddling.sum() > 100  # the edge's mixed pixels are in the comparison
