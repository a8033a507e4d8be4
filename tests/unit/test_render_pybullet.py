"""The TinyRenderer baseline against analytic geometry: depth, projection, object mask."""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.config import RenderConfig
from agrisim.plugins.render.pybullet_render import PybulletRenderOptions, agrisim_renderers
from agrisim.plugins.render.pybullet_render.renderer import PybulletRenderer
from agrisim.scene.camera import from_fov
from agrisim.scene.model import Label, LabelTable, Light, Material, Mesh, Scene
from agrisim.scene.transforms import look_at


def quad(name: str, half: float, z: float, material: Material) -> Mesh:
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]])
    return Mesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), [material], np.zeros(2), uvs=uv)


@pytest.fixture(scope="module")
def scene() -> Scene:
    floor = quad("floor", 5.0, 0.0, Material("floor", color=(0.5, 0.5, 0.5, 1.0), double_sided=False))
    albedo = np.zeros((8, 8, 4), np.uint8)
    albedo[..., 1] = 200
    albedo[:, :4, 3] = 0  # left half cut away: TinyRenderer cannot know
    albedo[:, 4:, 3] = 255
    plant = quad("plant", 0.1, 0.3, Material("leaf", albedo=albedo, alpha_mode="MASK", label=1))
    light = Light("sun", "area", np.array([0.0, 0.0, 3.0]), np.array([0.0, 0.0, -1.0]))
    return Scene(
        [floor, plant], [light], LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "plant", (0, 255, 0))])
    )


@pytest.fixture(scope="module")
def renderer(scene, cell):
    r = PybulletRenderer(scene, cell, RenderConfig(hide_robots=True), PybulletRenderOptions())
    yield r
    r.close()


def test_depth_is_metric_planar_z(renderer):
    """TinyRenderer's z-buffer, converted, is planar z, though not exactly: on this tilted floor
    of two large triangles it is off by about 0.5% (its interpolation is not exact), where
    the raycast renderer is exact."""
    cam = from_fov(90.0, 160, 120)
    # camera 1 m above the floor, tilted: planar z of the floor is known in closed form
    eye = np.array([0.0, -0.6, 1.0])
    T = look_at(eye, np.array([0.0, 0.2, 0.0]))
    frame = renderer.render(cam, T, {})
    K_inv = np.linalg.inv(cam.K)
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    rays = (K_inv @ np.stack([u.ravel(), v.ravel(), np.ones(u.size)])).T  # camera frame, z = 1
    world_dirs = rays @ T[:3, :3].T
    t = -eye[2] / world_dirs[:, 2]  # floor z = 0
    expected = t.reshape(cam.height, cam.width)  # z of the hit, since rays have z = 1
    floor = (frame.labels == 0) & (frame.depth > 0) & (expected > 0)
    rel = np.abs(frame.depth[floor] - expected[floor]) / expected[floor]
    assert floor.mean() > 0.5
    assert np.median(rel) < 1e-2 and np.percentile(rel, 99) < 3e-2


def test_projection_matches_the_intrinsics(renderer):
    """The plant quad (0.2 m at 0.7 m) covers exactly the pixels K predicts, within a pixel."""
    cam = from_fov(90.0, 160, 120)
    T = look_at(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0]), up=np.array([0.0, 1.0, 0.0]))
    frame = renderer.render(cam, T, {})
    ys, xs = np.nonzero(frame.labels)
    f = cam.fx
    half = 0.1 / 0.7 * f
    assert abs(xs.min() - (cam.cx - half)) <= 1.5 and abs(xs.max() - (cam.cx + half)) <= 1.5
    assert abs(ys.min() - (cam.cy - half)) <= 1.5 and abs(ys.max() - (cam.cy + half)) <= 1.5
    assert abs(float(frame.depth[int(cam.cy), int(cam.cx)]) - 0.7) < 1e-3


def test_no_opacity_cutouts_the_whole_card_is_plant(renderer):
    """TinyRenderer ignores alpha: the cut-away left half is drawn and labelled too."""
    cam = from_fov(90.0, 160, 120)
    T = look_at(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0]), up=np.array([0.0, 1.0, 0.0]))
    frame = renderer.render(cam, T, {})
    ys, xs = np.nonzero(frame.labels)
    assert xs.min() < cam.cx - 5 and xs.max() > cam.cx + 5


def test_it_declares_what_the_test_above_shows():
    """Whole cards are plant (RepOpa's masks) and there is one plant label: the spec says so,
    and the core refuses texture labels and organs for it (test_cli_errors, test_compare)."""
    (spec,) = agrisim_renderers()
    assert spec.capabilities.seg_modes == {"repopa"}
    assert not spec.capabilities.organ_labels and not spec.capabilities.leaf_instances


def test_arms_are_drawn_at_their_link_poses(scene, cell, kin):
    r = PybulletRenderer(scene, cell, RenderConfig(), PybulletRenderOptions())
    try:
        poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
        cam = from_fov(90.0, 160, 120)
        T = look_at(np.array([0.3, -1.0, 1.6]), np.array([1.0, 0.0, 1.2]))
        with_arm = r.render(cam, T, poses)
        far = {
            robot: {
                link: np.eye(4) @ np.diag([1, 1, 1, 1]) + np.array([[0, 0, 0, 50]] * 3 + [[0, 0, 0, 0]])
                for link in links
            }
            for robot, links in poses.items()
        }
        without = r.render(cam, T, far)
        assert (with_arm.depth != without.depth).mean() > 0.05
    finally:
        r.close()
