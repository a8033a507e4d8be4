"""The mitsuba renderer on an NVIDIA GPU (Mitsuba's ``cuda_ad_rgb``, OptiX). Marked ``gpu``: CI
has no GPU and skips them (tests/conftest.py); they run on the project's GPU machine from a
minimal install (no Open3D, pybullet, Pinocchio, OMPL or Rerun there), with ``--noconftest``.

Truths as on the CPU: K's projection of emissive markers, an integrating sphere's closed form,
and the CPU (LLVM) variant's image of the same saved frame.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from agrisim.plugins.render.mitsuba.camera import sensor_dict
from agrisim.plugins.render.mitsuba.scene import light_dict
from agrisim.plugins.render.mitsuba.variant import use_variant
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import Light
from agrisim.scene.transforms import look_at

pytestmark = pytest.mark.gpu


@pytest.fixture(scope="module")
def mi():  # noqa: ANN201
    return use_variant("cuda")


def render(mi, scene: dict, camera: CameraModel, T: np.ndarray, spp: int) -> np.ndarray:  # noqa: ANN001
    sensor = sensor_dict(camera, T, spp)
    sensor["to_world"] = mi.ScalarTransform4f(sensor["to_world"])
    return np.asarray(mi.render(mi.load_dict(scene), sensor=mi.load_dict(sensor), seed=1), np.float64)[..., :3]


def test_markers_land_on_their_k_projection_on_the_gpu(mi) -> None:  # noqa: ANN001
    camera = CameraModel(80, 60, 70.0, 70.0, 33.3, 27.6)
    T = look_at(np.array([0.3, -2.0, 1.2]), np.array([0.0, 0.0, 0.9]))
    R, t = T[:3, :3], T[:3, 3]
    scene: dict = {"type": "scene", "integrator": {"type": "path", "max_depth": 2}}
    points = []
    for i, ((du, dv), z) in enumerate(zip([(-20, -15), (18, -12), (0, 0), (22, 20)], [2.0, 2.4, 1.8, 2.6])):
        p = R @ np.array([du / camera.fx * z, dv / camera.fy * z, z]) + t
        points.append(p)
        M = np.eye(4)
        M[:3, :3] = R @ np.diag([2.0 / camera.fx * z, 2.0 / camera.fx * z, -2.0 / camera.fx * z])
        M[:3, 3] = p
        scene[f"m{i}"] = {"type": "disk", "to_world": mi.ScalarTransform4f(M), "emitter": {"type": "area", "radiance": 1.0}}
    image = render(mi, scene, camera, T, 1024)[..., 0]
    for p in points:
        q = camera.K @ (R.T @ (p - t))
        u, v = q[0] / q[2], q[1] / q[2]
        r0, c0 = int(round(v)), int(round(u))
        win = image[r0 - 5 : r0 + 6, c0 - 5 : c0 + 6]
        rows, cols = np.mgrid[r0 - 5 : r0 + 6, c0 - 5 : c0 + 6]
        cu, cv = (win * cols).sum() / win.sum(), (win * rows).sum() / win.sum()
        assert abs(cu - u) < 0.1 and abs(cv - v) < 0.1, (cu, u, cv, v)


def test_integrating_sphere_reaches_its_closed_form_on_the_gpu(mi) -> None:  # noqa: ANN001
    """As on the CPU: the indirect light in a closed Lambertian sphere (a icosahedral one built
    here, of area A) is pi a^2 I / (A (1 - a)) in raycast units."""
    a, intensity = 0.8, 2.0
    # an icosphere of 4 subdivisions, made without trimesh (not on the GPU machine)
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]  # fmt: skip
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]  # fmt: skip
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    faces = list(f)
    for _ in range(4):
        cache: dict = {}

        def mid(i: int, j: int) -> int:
            key = (min(i, j), max(i, j))
            if key not in cache:
                m = verts[i] + verts[j]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        faces = [tri for (i, j, k) in faces for tri in ((i, mid(i, j), mid(k, i)), (j, mid(j, k), mid(i, j)), (k, mid(k, i), mid(j, k)), (mid(i, j), mid(j, k), mid(k, i)))]
    V, F = np.array(verts), np.array(faces)
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum()
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [a] * 3}}})
    walls = mi.Mesh("sphere", len(V), len(F), props=props)
    params = mi.traverse(walls)
    params["vertex_positions"] = mi.Float(V.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(F.astype(np.uint32).ravel())
    params.update()
    light = Light("lamp", "area", np.zeros(3), np.array([0.0, 0.0, 1.0]), (1.0, 1.0, 1.0), intensity, 0.05)
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 100}, "walls": walls, "lamp": light_dict(light, mi.ScalarTransform4f)}
    camera = CameraModel(32, 24, 40.0, 40.0, 15.5, 11.5)
    value = render(mi, scene, camera, look_at(np.array([0.0, 0.3, -0.2]), np.array([0.0, 0.2, -1.0])), 1024).mean()
    expected = math.pi * a * a * intensity / (area * (1.0 - a))
    assert abs(value / expected - 1.0) < 0.03, (value, expected)


@pytest.mark.skipif(not os.environ.get("AGRISIM_GPU_RUN"), reason="AGRISIM_GPU_RUN names no saved run")
def test_rerender_on_the_gpu_matches_the_cpu_variant(tmp_path: Path) -> None:
    """``agrisim render`` of a saved run on CUDA: labels and depth are the run's own, and the RGB
    of each frame agrees with the CPU variant's (same scene and settings, 4 samples per pixel,
    other noise) to a few percent of mean brightness."""
    import subprocess
    import sys

    run = Path(os.environ["AGRISIM_GPU_RUN"])
    means = {}
    for variant in ("cuda", "llvm"):
        code = (
            "from agrisim.app.cli import main; import sys; "
            f"sys.exit(main(['render', {str(run)!r}, '--out', {str(tmp_path / variant)!r}, "
            f"'--set', 'renderer.mitsuba.variant={variant}', '--set', 'renderer.mitsuba.spp=4', '--set', 'renderer.mitsuba.denoise=off']))"
        )
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr
        from PIL import Image

        frames = sorted((tmp_path / variant / "rgb").glob("*.png"))
        assert frames
        means[variant] = np.array([np.asarray(Image.open(p), np.float64).mean() for p in frames])
        for folder in ("labels", "depth"):
            for p in (run / folder).glob("*.png"):
                assert (tmp_path / variant / folder / p.name).read_bytes() == p.read_bytes()
    np.testing.assert_allclose(means["cuda"], means["llvm"], rtol=0.03)
