"""nerfstudio's own dataparser reads agrisim's ``transforms.json`` through a lens: the camera
model and coefficients, and the rays nerfstudio makes for every pixel (its own undistortion,
its pixel centres at +0.5) are the rays agrisim rendered along (``cameras.json``'s lens).

Needs PyTorch and nerfstudio (not in the lock: nerfstudio pins half the ecosystem), so it runs
on the GPU machine, whose image has PyTorch, from wheels of nerfstudio and the few modules its
parser imports (viser, msgspec, websockets), on runs saved here: ``AGRISIM_NS_RUNS`` names a
folder of finished runs (one through the Camera Module 3 Wide's lens, a strong Brown-Conrady
lens, a fisheye), each with its ``transforms.json``. Marked ``gpu``: CI skips it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.gpu
torch = pytest.importorskip("torch")
pytest.importorskip("nerfstudio")
RUNS = Path(os.environ.get("AGRISIM_NS_RUNS", "/nonexistent"))
if not RUNS.is_dir():  # pragma: no cover - CI
    pytest.skip("AGRISIM_NS_RUNS names no folder of runs", allow_module_level=True)

from agrisim.files.rundir import camera_from_json  # noqa: E402


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles between unit vectors, precise when small (arccos of float32 dot products resolves
    no better than 3e-4 rad)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), (a * b).sum(-1))


def _rays_of_agrisim(camera, world_T_camera: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """H x W x 3 unit world directions of every pixel's ray, through agrisim's lens model."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float64)
    x, y = camera.rays(u, v)
    d = np.stack([x, y, np.ones_like(x)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return d @ world_T_camera[:3, :3].T


@pytest.mark.parametrize("run", sorted(p.name for p in RUNS.iterdir() if (p / "transforms.json").is_file()))
def test_nerfstudios_parser_makes_the_rays_agrisim_rendered(run: str) -> None:
    from nerfstudio.cameras.cameras import CAMERA_MODEL_TO_TYPE
    from nerfstudio.data.dataparsers.nerfstudio_dataparser import NerfstudioDataParserConfig

    root = RUNS / run
    transforms = json.loads((root / "transforms.json").read_text())
    cameras = json.loads((root / "cameras.json").read_text())
    camera = camera_from_json(cameras["intrinsics"])
    assert camera.distortion is not None
    config = NerfstudioDataParserConfig(
        data=root,
        orientation_method="none",
        center_method="none",
        auto_scale_poses=False,
        eval_mode="all",
        downscale_factor=1,
    )
    outputs = config.setup().get_dataparser_outputs(split="train")
    ns = outputs.cameras
    assert int(ns.camera_type[0]) == CAMERA_MODEL_TO_TYPE[transforms["camera_model"]].value
    # nerfstudio's order: k1, k2, k3, k4, p1, p2
    d = camera.distortion
    if camera.distortion.model == "fisheye":
        want = [*d.coefficients, 0.0, 0.0]
    else:
        k1, k2, p1, p2, k3 = d.coefficients
        want = [k1, k2, k3, 0.0, p1, p2]
    np.testing.assert_allclose(ns.distortion_params[0].numpy(), want, rtol=1e-6, atol=1e-7)
    pinhole = camera_from_json({**cameras["intrinsics"], "distortion": None})
    for i, path in enumerate(outputs.image_filenames):
        T = np.asarray(cameras["frames"][Path(path).stem]["world_T_camera"], np.float64)
        bundle = ns.generate_rays(camera_indices=i)
        theirs = bundle.directions.numpy().astype(np.float64)
        ours = _rays_of_agrisim(camera, T)
        np.testing.assert_allclose(bundle.origins.numpy()[0, 0], T[:3, 3], atol=1e-5)
        theirs /= np.linalg.norm(theirs, axis=-1, keepdims=True)
        angle = _angle(theirs, ours)
        # nerfstudio undistorts in float32 by Newton's method: measured 1.7-2.6e-7 rad (H200)
        assert angle.max() < 5e-6, (run, path, float(angle.max()))
        # and the lens matters: read as a pinhole, the corners' rays are 0.03-0.45 rad off
        off = _angle(theirs, _rays_of_agrisim(pinhole, T))
        assert off.max() > 0.01, (run, float(off.max()))
