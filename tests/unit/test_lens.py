"""Lenses (``core/scene/lens.py``) and rendering through them, checked by OpenCV:

* the forward models are ``cv2.projectPoints`` and ``cv2.fisheye.projectPoints`` to 1e-12, and
  the inverse undoes them;
* a lens that folds the image is refused, naming the radius where it turns;
* through a lens each pixel sees its own ray: on a board of labelled squares every pixel's label
  and depth are what OpenCV's ``undistortPoints`` says its ray meets (no pixel wrong, not even
  within a millionth of a square of an edge), and depth stays z along the axis;
* the calibration round trip: the Camera Module 3 Wide preset renders a checkerboard at 20 poses
  and OpenCV's ``calibrateCamera`` recovers its focal length and principal point within 0.5%, its
  k1 within 10% with the other coefficients near 0, at a reprojection RMS under 0.2 px
  (measured over pose seeds 0-2: focal 0.1-0.2%, k1 2-4%, RMS 0.11-0.14 px).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import kernels_launched

from agrisim.config import RenderConfig
from agrisim.errors import UserError
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.renderer import RaycastRenderer
from agrisim.scene.camera import CameraModel, preset
from agrisim.scene.lens import Distortion
from agrisim.scene.model import Label, LabelTable, Material, Mesh, Scene
from agrisim.scene.transforms import look_at

BARREL = Distortion("brown-conrady", (-0.2, 0.05, 0.001, -0.002, -0.005))
FISHEYE = Distortion("fisheye", (0.1, -0.02, 0.01, -0.002))
#: OpenCV's iterative inverse run to convergence (its default stops after 5 steps)
CONVERGED = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15)


def _opencv_project(lens: Distortion, xy: np.ndarray) -> np.ndarray:
    points = np.c_[xy, np.ones(len(xy))][:, None, :]
    if lens.model == "fisheye":
        out, _ = cv2.fisheye.projectPoints(points, np.zeros(3), np.zeros(3), np.eye(3), lens.opencv)
    else:
        out, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), np.eye(3), lens.opencv)
    return out[:, 0, :]


@pytest.mark.parametrize("lens", [BARREL, FISHEYE], ids=lambda lens: lens.model)
def test_the_models_are_opencvs_and_the_inverse_undoes_them(lens: Distortion) -> None:
    xy = np.random.default_rng(0).uniform(-0.8, 0.8, (2000, 2))
    xd, yd = lens.distort(xy[:, 0], xy[:, 1])
    np.testing.assert_allclose(np.c_[xd, yd], _opencv_project(lens, xy), atol=1e-12)
    x, y = lens.undistort(xd, yd)
    np.testing.assert_allclose(np.c_[x, y], xy, atol=1e-12)


def test_a_lens_that_folds_the_image_is_refused() -> None:
    folding = Distortion("brown-conrady", (-0.3, 0.1, 0.001, -0.002, -0.02))  # r_d peaks at 0.89
    with pytest.raises(UserError, match="folds the image: its distorted radius peaks at 0.89"):
        CameraModel(160, 120, 100.0, 100.0, 79.5, 59.5, folding)
    CameraModel(160, 120, 200.0, 200.0, 79.5, 59.5, folding)  # a narrower view stays short of the turn


def _board(z: float, n: int = 8, size: float = 0.08) -> Mesh:
    """n x n squares of ``size`` centred on the axis at depth z, labelled 1 and 2 alternately."""
    vertices, faces, material = [], [], []
    for i in range(n):
        for j in range(n):
            x0, y0, k = (j - n / 2) * size, (i - n / 2) * size, len(vertices)
            vertices += [[x0, y0, z], [x0 + size, y0, z], [x0 + size, y0 + size, z], [x0, y0 + size, z]]
            faces += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
            material += [(i + j) % 2] * 2
    materials = [Material("a", color=(0.9, 0.9, 0.9, 1.0), label=1), Material("b", color=(0.1, 0.1, 0.1, 1.0), label=2)]
    return Mesh("plant", np.array(vertices, float), np.array(faces), materials, np.array(material))


@pytest.mark.parametrize("lens", [BARREL, FISHEYE], ids=lambda lens: lens.model)
def test_each_pixel_sees_the_ray_opencv_gives_it(lens: Distortion) -> None:
    z, size = 0.5, 0.08
    camera = CameraModel(160, 120, 100.0, 100.0, 79.5, 59.5, lens)
    labels = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "a", (1, 1, 1)), Label(2, "b", (2, 2, 2))])
    renderer = RaycastRenderer(
        Scene([_board(z)], [], labels),
        None,
        RenderConfig(hide_robots=True, labels="organs"),
        RaycastOptions(variant="llvm", shadow_samples=0, supersample=2),  # (sub-pixel rays through the lens too)
    )
    frame = renderer.render(camera, np.eye(4), {})
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    pixels = np.c_[u.ravel(), v.ravel()][:, None, :]
    undistort = cv2.fisheye.undistortPoints if lens.model == "fisheye" else cv2.undistortPoints
    slopes = undistort(pixels, camera.K, lens.opencv, criteria=CONVERGED)[:, 0, :].reshape(
        camera.height, camera.width, 2
    )
    grid = slopes * z / size + 4  # where each ray meets the board, in squares from its corner
    inside = ((grid > 0) & (grid < 8)).all(axis=2)
    expected = np.where(inside, 1 + np.floor(grid).sum(axis=2) % 2, 0)
    clear = (np.abs(grid - np.round(grid)) > 1e-6).all(axis=2)  # not on an edge, to a millionth of a square
    assert clear.mean() > 0.99 and 0.3 < inside.mean() < 0.95
    assert (frame.labels[clear] == expected[clear]).all(), int((frame.labels[clear] != expected[clear]).sum())
    np.testing.assert_allclose(frame.depth[inside & clear], z, rtol=1e-6)  # z along the axis, not the ray's length
    assert (frame.depth[~inside & clear] == 0).all()


# ------------------------------------------------------------------ the calibration round trip

SQUARE, COLUMNS, ROWS = 0.03, 9, 7  # inner corners 8 x 6


def _checkerboard() -> Mesh:
    vertices, faces, material = [], [], []
    for i in range(ROWS):
        for j in range(COLUMNS):
            x0, y0, k = j * SQUARE, i * SQUARE, len(vertices)
            vertices += [[x0, y0, 0], [x0 + SQUARE, y0, 0], [x0 + SQUARE, y0 + SQUARE, 0], [x0, y0 + SQUARE, 0]]
            faces += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
            material += [(i + j) % 2] * 2
    m, k = SQUARE, len(vertices)  # the white margin a printed board has, just behind it
    vertices += [[-m, -m, -1e-4], [COLUMNS * SQUARE + m, -m, -1e-4], [COLUMNS * SQUARE + m, ROWS * SQUARE + m, -1e-4]]
    vertices += [[-m, ROWS * SQUARE + m, -1e-4]]
    faces += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
    material += [0, 0]
    materials = [Material("white", color=(0.9, 0.9, 0.9, 1.0)), Material("black", color=(0.02, 0.02, 0.02, 1.0))]
    return Mesh("board", np.array(vertices, float), np.array(faces), materials, np.array(material))


def _turn(to: np.ndarray) -> np.ndarray:
    """The rotation taking +z to the unit vector ``to`` (Rodrigues, about their cross product)."""
    v, c = np.cross([0.0, 0.0, 1.0], to), float(to[2])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


def _views(camera: CameraModel, seed: int) -> list[np.ndarray]:
    """20 poses 0.4-0.5 m off the board, tilted 10-40 degrees, the board's centre placed over a
    4 x 3 grid of the image (its edges, where the lens bends most, included)."""
    rng = np.random.default_rng(seed)
    centre = np.array([COLUMNS * SQUARE / 2, ROWS * SQUARE / 2, 0.0])
    spots = [(a, b) for a in (-0.45, -0.15, 0.15, 0.45) for b in (-0.35, 0.0, 0.35)]
    views = []
    for k in range(20):
        distance, tilt, azimuth = rng.uniform(0.4, 0.5), np.radians(rng.uniform(10, 40)), rng.uniform(0, 2 * np.pi)
        eye = centre + distance * np.array(
            [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)]
        )
        a, b = spots[k % len(spots)]
        toward = np.array([a * camera.width / 2 / camera.fx, b * camera.height / 2 / camera.fy, 1.0])
        turned = np.eye(4)
        turned[:3, :3] = _turn(toward / np.linalg.norm(toward)).T
        views.append(look_at(eye, centre, up=np.array([0.0, 1.0, 0.0])) @ turned)
    return views


def _board_corners(camera: CameraModel, seed: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The checkerboard rendered through ``camera`` at :func:`_views`' 20 poses: for each view
    where OpenCV finds it, its inner corners (board metres) and where they are (sub-pixel)."""
    renderer = RaycastRenderer(
        Scene([_checkerboard()], [], LabelTable()),
        None,
        RenderConfig(hide_robots=True),
        RaycastOptions(variant="llvm", shadow_samples=0, supersample=3),
    )
    board = np.array([[(j + 1) * SQUARE, (i + 1) * SQUARE, 0] for i in range(ROWS - 1) for j in range(COLUMNS - 1)])
    objects, corners = [], []
    for T in _views(camera, seed):
        grey = cv2.cvtColor(renderer.render(camera, T, {}).rgb, cv2.COLOR_RGB2GRAY)
        found, at = cv2.findChessboardCorners(grey, (COLUMNS - 1, ROWS - 1))
        if found:
            stop = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
            corners.append(cv2.cornerSubPix(grey, at, (5, 5), (-1, -1), stop))
            objects.append(board)
    return objects, corners


@pytest.mark.parametrize("lens", [BARREL, FISHEYE])
def test_every_pose_reuses_the_first_views_kernels(lens: Distortion) -> None:
    """Views through a lens from other poses launch the first view's kernels again, compiling
    none: a view's pose is data, not code (as literals each view compiled its own kernel,
    0.3 s a view on an Intel Xeon with AVX-512 and 1.4 s with AVX2)."""
    camera = CameraModel(96, 54, 60.0, 60.0, 47.5, 26.5, lens)
    renderer = RaycastRenderer(
        Scene([_checkerboard()], [], LabelTable()),
        None,
        RenderConfig(hide_robots=True),
        RaycastOptions(variant="llvm", shadow_samples=0),
    )
    views = _views(camera, seed=3)[:3]
    first = kernels_launched(lambda: renderer.render(camera, views[0], {}))
    for T in views[1:]:
        again = kernels_launched(lambda T=T: renderer.render(camera, T, {}))
        assert again and {k.hash for k in again} <= {k.hash for k in first}
        assert not any(k.fresh for k in again)


def test_opencv_calibrates_the_rendered_lens_back() -> None:
    camera = preset("rpi-camera-3-wide", "640x360")
    objects, corners = _board_corners(camera, seed=0)
    assert len(corners) >= 18, f"the board found in {len(corners)} of 20 views"
    objects = [o.astype(np.float32) for o in objects]
    rms, K, D, _, _ = cv2.calibrateCamera(
        objects, corners, (camera.width, camera.height), None, None, flags=cv2.CALIB_FIX_K3
    )
    k1, k2, p1, p2, _ = D.ravel()
    truth = camera.distortion.coefficients[0]  # type: ignore[union-attr]
    assert rms < 0.2, rms
    np.testing.assert_allclose(
        [K[0, 0], K[1, 1], K[0, 2], K[1, 2]], [camera.fx, camera.fy, camera.cx, camera.cy], rtol=0.005
    )
    assert abs(k1 / truth - 1) < 0.1 and max(abs(k2), abs(p1), abs(p2)) < 0.005, (k1, truth, D.ravel())


def test_opencv_calibrates_a_rendered_fisheye_back() -> None:
    """The same round trip through a fisheye (Kannala-Brandt, 140 degrees across) with
    ``cv2.fisheye.calibrate``: focal length and principal point within 0.5%, k1 within 0.02."""
    lens = Distortion("fisheye", (0.05, -0.005, 0.0, 0.0))
    camera = CameraModel(640, 360, 250.0, 250.0, 319.5, 179.5, lens)
    objects, corners = _board_corners(camera, seed=1)
    # cv2.fisheye wants each view's points as one row of float64
    objects = [o.reshape(1, -1, 3).astype(np.float64) for o in objects]
    corners = [c.reshape(1, -1, 2).astype(np.float64) for c in corners]
    assert len(corners) >= 15, f"the board found in {len(corners)} of 20 views"
    flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
    stop = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 200, 1e-12)
    rms, K, D, _, _ = cv2.fisheye.calibrate(
        objects, corners, (camera.width, camera.height), None, None, flags=flags, criteria=stop
    )
    assert rms < 0.2, rms
    np.testing.assert_allclose(
        [K[0, 0], K[1, 1], K[0, 2], K[1, 2]], [camera.fx, camera.fy, camera.cx, camera.cy], rtol=0.005
    )
    assert abs(D.ravel()[0] - lens.coefficients[0]) < 0.02, D.ravel()


@pytest.mark.parametrize("lens", [BARREL, Distortion("brown-conrady", (-0.2, 0.05, 0.001, -0.002, 0.0)), FISHEYE])
def test_pycolmap_projects_through_the_camera_agrisim_gives_it(lens: Distortion) -> None:
    """``agrisim colmap``'s known camera (FULL_OPENCV, OPENCV or OPENCV_FISHEYE) read by pycolmap
    lands every point where agrisim's lens does, half a pixel over (COLMAP's first pixel centre
    is at 0.5)."""
    import pycolmap

    from agrisim.plugins.poses.colmap.photogrammetry import colmap_camera

    camera = CameraModel(320, 180, 150.0, 151.0, 159.5, 89.5, lens)
    model, params = colmap_camera(camera.K, lens.as_dict())
    theirs = pycolmap.Camera(model=model, width=camera.width, height=camera.height, params=params)
    xy = np.random.default_rng(1).uniform(-0.7, 0.7, (500, 2))
    u, v = camera.project(xy[:, 0], xy[:, 1])
    np.testing.assert_allclose(theirs.img_from_cam(np.c_[xy, np.ones(len(xy))]), np.c_[u, v] + 0.5, atol=1e-9)


@pytest.mark.parametrize("lens", [BARREL, FISHEYE], ids=lambda lens: lens.model)
def test_the_path_tracer_sees_through_the_lens(lens: Distortion) -> None:
    """``mitsuba`` through a lens (its ``agrisim_lens`` sensor): every pixel well inside a square
    of the board, by OpenCV's ``undistortPoints``, is bright on a light square and dark on a dark
    one; labels and depth are raycast's, which the test above holds to OpenCV."""
    from agrisim.plugins.render.mitsuba import MitsubaOptions
    from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer
    from agrisim.scene.model import Light

    z, size = 0.5, 0.08
    camera = CameraModel(160, 120, 100.0, 100.0, 79.5, 59.5, lens)
    light = Light("lamp", "point", np.array([0.3, 0.3, -0.5]), np.array([0.0, 0.0, 1.0]), intensity=1.0)
    # the camera's own housing, 0.5 mm before its centre: rays start at the near plane (1 mm), as
    # Mitsuba's perspective sensor's and raycast's do
    v = np.array([[-2, -2, 0.5], [2, -2, 0.5], [2, 2, 0.5], [-2, 2, 0.5]]) * 1e-3  # (its shadow falls off the board)
    housing = Mesh("housing", v, np.array([[0, 1, 2], [0, 2, 3]]), [Material("housing")], np.zeros(2, int))
    labels = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "a", (1, 1, 1))])
    scene = Scene([_board(z), housing], [light], labels)
    options = MitsubaOptions(variant="llvm", spp=8, denoise="off")
    radiance = MitsubaRenderer(scene, None, RenderConfig(hide_robots=True), options).radiance(camera, np.eye(4))
    grey = radiance.mean(axis=2)
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    undistort = cv2.fisheye.undistortPoints if lens.model == "fisheye" else cv2.undistortPoints
    pixels = np.c_[u.ravel(), v.ravel()][:, None, :]
    slopes = undistort(pixels, camera.K, lens.opencv, criteria=CONVERGED)[:, 0, :].reshape(
        camera.height, camera.width, 2
    )
    grid = slopes * z / size + 4
    inside = ((grid > 0) & (grid < 8)).all(axis=2)
    well_inside = inside & (np.abs(grid - np.round(grid)) > 0.15).all(axis=2)  # a pixel's samples off the edges
    light_square = np.floor(grid).sum(axis=2) % 2 == 0
    threshold = 0.5 * (np.median(grey[well_inside & light_square]) + np.median(grey[well_inside & ~light_square]))
    assert ((grey > threshold) == light_square)[well_inside].mean() > 0.999


@pytest.mark.parametrize("lens", [BARREL, FISHEYE], ids=lambda lens: lens.model)
def test_a_lens_view_resampled_onto_its_pinhole_is_the_pinholes_view(lens: Distortion) -> None:
    """``as_pinhole`` (for reconstructors that read pinholes: the TSDF): the board seen through
    the lens and resampled onto the pinhole of its K is what the pinhole itself renders: labels
    and depth, to within a pixel of the squares' edges (nearest-neighbour resampling)."""
    from agrisim.evaluation.views import as_pinhole
    from agrisim.interfaces import View

    labels = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "a", (1, 1, 1)), Label(2, "b", (2, 2, 2))])
    renderer = RaycastRenderer(
        Scene([_board(0.5)], [], labels),
        None,
        RenderConfig(hide_robots=True, labels="organs"),
        RaycastOptions(variant="llvm", shadow_samples=0),
    )
    through = CameraModel(240, 180, 150.0, 150.0, 119.5, 89.5, lens)
    pinhole = CameraModel(240, 180, 150.0, 150.0, 119.5, 89.5)
    lens_view = View("v", through, np.eye(4), renderer.render(through, np.eye(4), {}))
    resampled = as_pinhole(lens_view).images
    truth = renderer.render(pinhole, np.eye(4), {})
    # a pixel whose 3x3 neighbourhood has one label in the truth: not within a pixel of an edge
    padded = np.pad(truth.labels, 1, mode="edge")
    window = np.stack([padded[dy : dy + 180, dx : dx + 240] for dy in range(3) for dx in range(3)])
    uniform = (window == truth.labels).all(axis=0)
    seen = resampled.labels > 0  # (the lens image covers only part of the pinhole's corners)
    assert (uniform & seen).mean() > 0.5
    np.testing.assert_array_equal(resampled.labels[uniform & seen], truth.labels[uniform & seen])
    np.testing.assert_allclose(resampled.depth[uniform & seen], truth.depth[uniform & seen], rtol=1e-6)
    # the splat reconstructor trains on exactly these pinhole views (gsplat rasterises pinholes)
    from agrisim.plugins.recon.splat.reconstructor import SplatReconstructor

    splat = SplatReconstructor(labels)
    splat.integrate(lens_view)
    assert splat.views[0].camera == pinhole
    np.testing.assert_array_equal(splat.views[0].images.rgb, resampled.rgb)


def test_a_reconstructor_that_reads_pinholes_only_refuses_a_lens() -> None:
    """A plugin's reconstructor that does not declare ``lenses`` is refused a lens's views in one
    line naming what can; the built-in ones all read them (splat through undistorted views)."""
    from agrisim.capabilities import ReconstructorCapabilities, check_reconstructor
    from agrisim.registry import BackendSpec, Registry, make_plugin_manager

    pinholes_only = BackendSpec(
        name="my-nerf",
        factory=lambda *a: None,
        description="a NeRF of pinhole views",
        capabilities=ReconstructorCapabilities(lenses=False),
    )
    with pytest.raises(UserError, match="'my-nerf' reads pinhole views only.*pointcloud"):
        check_reconstructor(pinholes_only, hide_robots=True, lens=True)
    check_reconstructor(pinholes_only, hide_robots=True, lens=False)
    built_in = Registry(make_plugin_manager()).specs("reconstructor")
    assert all(spec.capabilities.lenses for spec in built_in.values()), sorted(built_in)
