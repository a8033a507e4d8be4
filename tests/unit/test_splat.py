"""The ``splat`` reconstructor's parts that need no GPU (CI runs these; the training itself is in
tests/gpu/test_splat_cuda.py). Truths: scikit-image's PSNR and SSIM, trimesh's PLY reader,
OpenCV's pinhole projection of ``cameras.json``'s K and pose, and the refusals' own promises
(exit 2, one line, nothing written)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import small_run
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from agrisim.errors import OutputError, UserError
from agrisim.plugins.apps.recon import check_writable
from agrisim.plugins.recon.splat.cameras import downscale_image, gsplat_camera
from agrisim.plugins.recon.splat.ply import splat_ply
from agrisim.plugins.recon.splat.quality import psnr, ssim
from agrisim.plugins.recon.splat.split import minimum_views, split_views
from agrisim.scene.model import Label, LabelTable
from agrisim.scene.transforms import look_at

FRAMES = [f"r{1 + i % 2}_{i // 2:03d}" for i in range(100)]


def test_split_is_seeded_disjoint_and_the_papers_share() -> None:
    train, test = split_views(FRAMES, 0.1, seed=7)
    assert len(test) == 10 and len(train) == 90
    assert not set(train) & set(test) and sorted(train + test) == sorted(FRAMES)
    assert split_views(FRAMES, 0.1, seed=7) == (train, test)  # the same seed: the same split
    assert split_views(FRAMES, 0.1, seed=8)[1] != test
    assert [f for f in FRAMES if f in set(test)] == test  # capture order kept


def test_too_few_views_are_refused_naming_the_minimum() -> None:
    n = minimum_views(0.1)
    split_views(FRAMES[:n], 0.1, 0)
    with pytest.raises(UserError, match=f"at least {n}"):
        split_views(FRAMES[: n - 1], 0.1, 0)


@pytest.mark.parametrize("downscale", [1, 2, 4])
def test_gsplat_camera_puts_points_on_their_opencv_pixels(downscale: int) -> None:
    """World points through the matrices handed to gsplat (its pixel centres at +0.5) land on
    the pixel OpenCV's K and the pose put them on, in the box-downscaled image too: OpenCV's
    (u, v) is corner coordinate (u + 0.5, v + 0.5), divided by the downscale factor."""
    K = np.array([[800.0, 0.0, 470.3], [0.0, 800.0, 265.9], [0.0, 0.0, 1.0]])
    T = look_at(np.array([0.4, -0.9, 1.3]), np.array([0.0, 0.0, 0.9]))
    rng = np.random.default_rng(2)
    points = rng.uniform([-0.2, -0.2, 0.8], [0.2, 0.2, 1.1], (50, 3))
    cam = (points - T[:3, 3]) @ T[:3, :3]
    opencv = (cam @ K.T)[:, :2] / cam[:, 2:]
    viewmat, Kg = gsplat_camera(K, T, downscale)
    p = np.column_stack([points, np.ones(len(points))]) @ viewmat.T
    corner = (p[:, :3] @ Kg.T)[:, :2] / p[:, 2:3]
    assert np.allclose(corner * downscale - 0.5, opencv, atol=1e-9)
    assert np.allclose(viewmat @ T, np.eye(4), atol=1e-12)


def test_downscale_averages_blocks() -> None:
    image = np.arange(6 * 8, dtype=np.float64).reshape(6, 8)
    small = downscale_image(image, 2)
    assert small.shape == (3, 4) and small[0, 0] == (0 + 1 + 8 + 9) / 4


def _natural(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """A smooth random image in [0, 1] (noise blurred by cumulative sums)."""
    x = rng.random(shape).cumsum(axis=0).cumsum(axis=1)
    x -= x.min()
    return x / x.max()


def test_psnr_and_ssim_agree_with_scikit_image() -> None:
    rng = np.random.default_rng(0)
    a = _natural(rng, (64, 80, 3))
    b = np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1)
    assert psnr(a, b) == pytest.approx(peak_signal_noise_ratio(a, b, data_range=1.0), rel=1e-12)
    reference = structural_similarity(
        a, b, data_range=1.0, channel_axis=2, gaussian_weights=True, sigma=1.5, use_sample_covariance=False
    )
    assert ssim(a, b) == pytest.approx(reference, abs=1e-9)
    assert ssim(a, a) == pytest.approx(1.0) and psnr(a, a) == float("inf")
    mask = rng.random(a.shape[:2]) < 0.3
    assert psnr(a, b, mask) == pytest.approx(peak_signal_noise_ratio(a[mask], b[mask], data_range=1.0), rel=1e-12)


def test_splat_ply_reads_back_with_trimesh_in_the_viewers_layout(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    n, k = 40, 15
    means, quats = rng.normal(size=(n, 3)), rng.normal(size=(n, 4))
    log_scales, opacity = rng.normal(size=(n, 3)), rng.normal(size=n)
    sh0, sh_rest = rng.normal(size=(n, 3)), rng.normal(size=(n, k, 3))
    path = tmp_path / "splats.ply"
    path.write_bytes(splat_ply(means, quats, log_scales, opacity, sh0, sh_rest))
    data = trimesh.load(path).metadata["_ply_raw"]["vertex"]["data"]
    names = list(data.dtype.names)
    assert names[:9] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    assert names[9 : 9 + 3 * k] == [f"f_rest_{i}" for i in range(3 * k)]
    assert names[9 + 3 * k :] == ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    assert all(data.dtype[name] == np.float32 for name in names) and len(data) == n
    f32 = lambda a: a.astype(np.float32)  # noqa: E731
    assert np.array_equal(np.column_stack([data["x"], data["y"], data["z"]]), f32(means))
    assert np.array_equal(data["opacity"], f32(opacity)) and np.array_equal(data["rot_0"], f32(quats[:, 0]))
    # f_rest: all of red's coefficients, then green's, then blue's
    for c in range(3):
        for j in range(k):
            assert np.array_equal(data[f"f_rest_{c * k + j}"], f32(sh_rest[:, j, c]))


def test_an_existing_splat_folder_needs_overwrite(tmp_path: Path) -> None:
    table = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "plant", (0, 255, 0))])
    check_writable(tmp_path, table, False, "splat")
    (tmp_path / "splat").mkdir()
    with pytest.raises(OutputError, match="splat already exists"):
        check_writable(tmp_path, table, False, "splat")
    check_writable(tmp_path, table, True, "splat")


def _run(out: Path, hide_robots: bool) -> Path:
    return small_run(
        out,
        plant="indian_cress",
        render={"hide_robots": hide_robots},
        camera={"resolution": "64x36"},
        recon={"backend": "none"},
    )


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[bool, Path]:
    root = tmp_path_factory.mktemp("splat")
    return {hidden: _run(root / f"hidden_{hidden}", hidden) for hidden in (True, False)}


def _listing(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


def test_refusals_write_nothing(runs: dict[bool, Path], cli, tmp_path: Path) -> None:  # noqa: ANN001
    """Arms in view; no CUDA GPU (CI: no PyTorch); ``agrisim run --recon splat`` without
    --hide-robots: exit 2, one line, nothing written."""
    import importlib.util

    before = {h: _listing(p) for h, p in runs.items()}
    code, _, err = cli(["recon", str(runs[False]), "--recon", "splat"])
    assert code == 2 and "--hide-robots" in err and len(err.strip().splitlines()) == 1
    if importlib.util.find_spec("torch") is None or importlib.util.find_spec("gsplat") is None:
        code, _, err = cli(["recon", str(runs[True]), "--recon", "splat"])
        assert code == 2 and len(err.strip().splitlines()) == 1
        assert "needs a CUDA GPU" in err or "needs gsplat" in err
    out = tmp_path / "new"
    code, _, err = cli(["run", "--plant", "indian_cress", "--recon", "splat", "--setpoints", "1x3", "--out", str(out)])
    assert code == 2 and "--hide-robots" in err and not out.exists()
    assert {h: _listing(p) for h, p in runs.items()} == before


def test_training_recording_reads_back_with_rerun(tmp_path: Path) -> None:
    """The loss on the step timeline (one chunk per column), the test images and the centres,
    read back by Rerun's own reader."""
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    from agrisim.plugins.recon.splat.recording import TIMELINE, training_recording

    rng = np.random.default_rng(6)
    loss = [(s, 1.0 / (1 + s), 1000 + s) for s in range(0, 500, 10)]
    tests = {"r1_003": rng.integers(0, 256, (12, 30, 3), dtype=np.uint8)}
    centres = rng.normal(size=(25, 3))
    data = training_recording(loss, tests, centres, rng.integers(0, 256, (25, 3), dtype=np.uint8), np.full(25, 0.001))
    path = tmp_path / "training.rrd"
    path.write_bytes(data)
    chunks: dict[str, list] = {}
    for chunk in RrdReader(path).stream():
        chunks.setdefault(chunk.entity_path.lstrip("/"), []).append(chunk.to_record_batch())
    (batch,) = chunks["training/loss"]
    scalars = [c for c in batch.schema.names if c.endswith("scalars")]
    assert batch.column(TIMELINE).to_pylist() == [s for s, _, _ in loss]
    assert np.allclose(np.concatenate(batch.column(scalars[0]).to_pylist()), [x for _, x, _ in loss])
    assert "test/r1_003" in chunks
    (points,) = chunks["world/splat_centres"]
    positions = [c for c in points.schema.names if c.endswith("positions")]
    assert np.allclose(np.array(points.column(positions[0]).to_pylist()[0]), centres.astype(np.float32))


def test_a_replaced_folder_keeps_nothing_stale(tmp_path: Path) -> None:
    from agrisim.interfaces import Reconstruction
    from agrisim.plugins.sinks.dataset.reconstruction import write_reconstruction

    write_reconstruction(tmp_path, Reconstruction(files={"splat/test/a.png": b"1", "splat/split.json": b"{}"}), {})
    write_reconstruction(tmp_path, Reconstruction(files={"splat/test/b.png": b"2", "splat/split.json": b"[]"}), {})
    assert sorted(str(p.relative_to(tmp_path / "splat")) for p in (tmp_path / "splat").rglob("*") if p.is_file()) == [
        "split.json",
        "test/b.png",
    ]
    assert (tmp_path / "splat" / "split.json").read_bytes() == b"[]"


@pytest.mark.parametrize("share", [0.0, 0.5, 1.0])
def test_plant_init_draws_its_share_of_the_initial_gaussians_on_the_plant(runs: dict[bool, Path], share: float) -> None:
    """``plant_init``: that share of the initial Gaussians lies on the true plant surface (the
    saved scene's plant mesh, Open3D's distance to it), the rest on the whole image, where the
    plant has its share of the pixels."""
    import json

    from agrisim.evaluation.views import load_view
    from agrisim.files import layout
    from agrisim.files.rundir import camera_from_json
    from agrisim.plugins.formats.scene_glb import read_scene
    from agrisim.plugins.recon.splat.options import SplatOptions
    from agrisim.plugins.recon.splat.reconstructor import SplatReconstructor

    run = runs[True]
    cameras = json.loads((run / layout.CAMERAS_JSON).read_text())
    camera = camera_from_json(cameras["intrinsics"])
    views = [load_view(run, f, camera, np.asarray(d["world_T_camera"])) for f, d in cameras["frames"].items()]
    plant_pixels = np.mean([np.mean(v.images.labels != 0) for v in views])
    assert 0.02 < plant_pixels < 0.5
    scene = read_scene(run / layout.SCENE_GLB)
    surface = scene.plant_surface()
    assert surface is not None
    rec = SplatReconstructor(scene.labels, SplatOptions(plant_init=share, init_points=1000))
    points, colors = rec._initial_points(views, np.random.default_rng(0))
    assert points.shape == (1000, 3) and colors.shape == (1000, 3)
    import open3d as o3d

    surfaces = o3d.t.geometry.RaycastingScene()
    surfaces.add_triangles(surface.vertices.astype(np.float32), surface.faces.astype(np.uint32))
    distance = surfaces.compute_distance(points.astype(np.float32)).numpy()
    on_plant = np.mean(distance < 0.003)  # depth is stored in whole millimetres
    expected = share + (1 - share) * plant_pixels
    assert abs(on_plant - expected) < 0.06, (on_plant, expected)
