"""Rendering through a lens on an NVIDIA GPU (Dr.Jit's CUDA backend, OptiX): the lens's inverse
solved in the kernels there (double precision on the GPU) gives what it gives on the CPU.
Marked ``gpu``: CI skips it; it runs on the project's GPU machine from the minimal install
(no OpenCV there: the truth is :meth:`CameraModel.rays` on the host, which
tests/unit/test_lens.py holds to OpenCV's ``undistortPoints``).

* raycast's labels and depth on a board of labelled squares: every pixel clear of an edge has
  its square's label, and the board's depth;
* mitsuba's path-traced board (``agrisim_lens``): light and dark where the squares are (one
  Mitsuba variant a process: the CPU's image is tests/unit/test_lens.py's).
"""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.config import RenderConfig
from agrisim.scene.camera import CameraModel
from agrisim.scene.lens import Distortion
from agrisim.scene.model import Label, LabelTable, Light, Material, Mesh, Scene

pytestmark = pytest.mark.gpu

LENSES = [
    Distortion("brown-conrady", (-0.2, 0.05, 0.001, -0.002, -0.005)),
    Distortion("fisheye", (0.1, -0.02, 0.01, -0.002)),
]
Z, SIZE = 0.5, 0.08


def _board() -> Mesh:
    vertices, faces, material = [], [], []
    for i in range(8):
        for j in range(8):
            x0, y0, k = (j - 4) * SIZE, (i - 4) * SIZE, len(vertices)
            vertices += [[x0, y0, Z], [x0 + SIZE, y0, Z], [x0 + SIZE, y0 + SIZE, Z], [x0, y0 + SIZE, Z]]
            faces += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
            material += [(i + j) % 2] * 2
    materials = [Material("a", color=(0.9, 0.9, 0.9, 1.0), label=1), Material("b", color=(0.1, 0.1, 0.1, 1.0), label=2)]
    return Mesh("plant", np.array(vertices, float), np.array(faces), materials, np.array(material))


def _truth(camera: CameraModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel: inside the board, clear of its edges (by ``margin`` of a square), light square."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    x, y = camera.rays(u, v)
    grid = np.stack([x, y], -1) * Z / SIZE + 4
    inside = ((grid > 0) & (grid < 8)).all(axis=2)
    offset = np.abs(grid - np.round(grid)).min(axis=2)
    return inside, offset, np.floor(grid).sum(axis=2) % 2 == 0


SCENE_LABELS = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "a", (1, 1, 1)), Label(2, "b", (2, 2, 2))])


@pytest.mark.parametrize("lens", LENSES, ids=lambda lens: lens.model)
def test_raycast_through_a_lens_on_the_gpu(lens: Distortion) -> None:
    from agrisim.plugins.render.raycast import RaycastOptions
    from agrisim.plugins.render.raycast.renderer import RaycastRenderer

    camera = CameraModel(320, 240, 200.0, 200.0, 159.5, 119.5, lens)
    renderer = RaycastRenderer(
        Scene([_board()], [], SCENE_LABELS),
        None,
        RenderConfig(hide_robots=True, labels="organs"),
        RaycastOptions(variant="cuda", shadow_samples=0),
    )
    frame = renderer.render(camera, np.eye(4), {})
    inside, offset, light = _truth(camera)
    clear = inside & (offset > 1e-5)
    expected = np.where(light, 1, 2)
    assert clear.mean() > 0.3
    assert (frame.labels[clear] == expected[clear]).all(), int((frame.labels[clear] != expected[clear]).sum())
    np.testing.assert_allclose(frame.depth[clear], Z, rtol=1e-6)


@pytest.mark.parametrize("lens", LENSES, ids=lambda lens: lens.model)
def test_the_path_tracer_through_a_lens_on_the_gpu(lens: Distortion) -> None:
    from agrisim.plugins.render.mitsuba import MitsubaOptions
    from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer

    camera = CameraModel(320, 240, 200.0, 200.0, 159.5, 119.5, lens)
    light = Light("lamp", "point", np.array([0.3, 0.3, -0.5]), np.array([0.0, 0.0, 1.0]))
    scene = Scene([_board()], [light], SCENE_LABELS)
    inside, offset, light_square = _truth(camera)
    well_inside = inside & (offset > 0.15)
    options = MitsubaOptions(variant="cuda", spp=16, denoise="off")
    grey = (
        MitsubaRenderer(scene, None, RenderConfig(hide_robots=True), options).radiance(camera, np.eye(4)).mean(axis=2)
    )
    threshold = 0.5 * (np.median(grey[well_inside & light_square]) + np.median(grey[well_inside & ~light_square]))
    assert ((grey > threshold) == light_square)[well_inside].mean() > 0.999
