"""``agrisim colmap``: COLMAP (pycolmap) on a small run's views, scored against the cameras the
run really had. The truth: ``cameras.json``; the scores re-derived from the written model with
pycolmap's own similarity estimate (a second implementation of the alignment); the refusals
(exit 2, one line, nothing written or replaced)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pycolmap
import pytest
from conftest import small_run

from agrisim.evaluation.photogrammetry import COLMAP_DIR, POSES_JSON


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """36 views of coltsfoot, 960x540, the arms hidden (they move between views), eight shadow
    rays a pixel (one gives speckle that SIFT takes for texture), from the part of the
    hemisphere where neighbouring views overlap."""
    out = tmp_path_factory.mktemp("colmap") / "run"
    return small_run(
        out,
        plant="coltsfoot",
        routine={"setpoints": "3x6", "theta_deg": [50.0, 130.0], "phi_deg": [40.0, 70.0]},
        camera={"resolution": "960x540"},
        render={"hide_robots": True},
        renderer={"raycast": {"shadow_samples": 8}},
        recon={"backend": "none"},
    )


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0))))


def test_colmap_recovers_the_cameras_within_a_bound_of_the_truth(run_dir: Path, cli) -> None:  # noqa: ANN001
    code, out, err = cli(["colmap", str(run_dir)])
    assert code == 0, err
    assert f"wrote {run_dir / COLMAP_DIR}" in out
    doc = json.loads((run_dir / COLMAP_DIR / POSES_JSON).read_text())
    truth = json.loads((run_dir / "cameras.json").read_text())["frames"]
    summary, views = doc["summary"], doc["views"]
    assert summary["views"] == len(truth) == 36
    # measured 18 (exhaustive matching, one model); COLMAP's threads make it vary a little
    assert summary["registered"] >= 10, summary
    assert summary["median_centre_error_mm"] < 15.0 and summary["median_rotation_error_deg"] < 1.0, summary
    assert summary["reprojection_px"] < 1.5
    # a metre in the world is 1/scale model units: COLMAP's scale is arbitrary, never metres
    assert summary["scale_m_per_unit"] > 0

    # The scores again from the written model, aligned by pycolmap's own similarity estimate
    # fitted to the views placed within 20 mm (all of them here)
    model = pycolmap.Reconstruction(run_dir / COLMAP_DIR / "sparse" / "0")
    registered = {img.name.removesuffix(".png"): img for img in model.images.values() if img.has_pose}
    assert sorted(registered) == sorted(v["frame"] for v in views if v["registered"])
    by_frame = {v["frame"]: v for v in views}
    frames = sorted(registered)
    assert summary["within_20mm"] == sum(by_frame[f]["centre_error_mm"] <= 20.0 for f in frames)
    centres = np.array([registered[f].projection_center() for f in frames])
    true_T = {f: np.asarray(truth[f]["world_T_camera"], float) for f in frames}
    near = np.array([by_frame[f]["centre_error_mm"] <= 20.0 for f in frames])
    sim = pycolmap.estimate_sim3d(centres[near], np.array([true_T[f][:3, 3] for f in frames])[near])
    M = np.asarray(sim.matrix())
    aligned = centres @ M[:3, :3].T + M[:3, 3]
    for f, c in zip(frames, aligned, strict=True):
        assert by_frame[f]["centre_error_mm"] == pytest.approx(np.linalg.norm(c - true_T[f][:3, 3]) * 1e3, abs=1e-3)
        # the pose a reconstruction on COLMAP's cameras gets: the same centre
        np.testing.assert_allclose(np.asarray(by_frame[f]["world_T_camera"])[:3, 3], c, atol=1e-6)
    # rotations: errors are what is left after the one best turn; relative rotations between
    # views need no alignment at all and must agree with the truth's as closely
    model_R = {f: np.asarray(registered[f].cam_from_world().rotation.matrix()).T for f in frames}
    worst = max(v["rotation_error_deg"] for v in views if v["registered"])
    for a, b in zip(frames, frames[1:], strict=False):
        relative = _angle_deg(true_T[a][:3, :3].T @ true_T[b][:3, :3], model_R[a].T @ model_R[b])
        assert relative <= 2.0 * worst + 1e-6
    for v in views:
        if not v["registered"]:
            assert v["centre_error_mm"] is None and v["rotation_error_deg"] is None
    assert not (run_dir / COLMAP_DIR / "database.db").exists()


def test_a_reconstruction_on_colmaps_poses_costs_accuracy(run_dir: Path, cli, tmp_path: Path) -> None:  # noqa: ANN001
    """``agrisim recon --set recon.poses=colmap``: only the views COLMAP placed, at its poses
    moved into the world; the plant's cloud stays near the true surface (COLMAP's cameras are
    millimetres off) but is measurably less precise than on the true poses."""
    poses_json = run_dir / COLMAP_DIR / POSES_JSON
    if not poses_json.exists() or json.loads(poses_json.read_text())["colmap"]["matcher"] != "exhaustive":
        assert cli(["colmap", str(run_dir), "--overwrite"])[0] == 0  # (run alone: the first test's model)
    registered = json.loads((run_dir / COLMAP_DIR / POSES_JSON).read_text())["summary"]["registered"]
    metrics = {}
    for poses in ("colmap", "truth"):
        out = tmp_path / poses
        code, _, err = cli(
            ["recon", str(run_dir), "--recon", "pointcloud", "--set", f"recon.poses={poses}", "--out", str(out)]
        )
        assert code == 0, err
        metrics[poses] = json.loads((out / "metrics.json").read_text())
    assert metrics["colmap"]["poses"] == "colmap" and metrics["colmap"]["frames"] == registered
    assert metrics["truth"]["frames"] == 36
    plant = {k: m["labels"]["plant"] for k, m in metrics.items()}
    assert plant["colmap"]["precision"]["5"] > 0.8
    assert plant["colmap"]["precision"]["1"] < plant["truth"]["precision"]["1"] - 0.1
    assert plant["colmap"]["chamfer_mm"] > plant["truth"]["chamfer_mm"]


def test_sequential_matching_replaces_the_model_only_with_overwrite(run_dir: Path, cli) -> None:  # noqa: ANN001
    if not (run_dir / COLMAP_DIR).exists():
        assert cli(["colmap", str(run_dir)])[0] == 0
    before = (run_dir / COLMAP_DIR / POSES_JSON).read_bytes()
    code, _, err = cli(["colmap", str(run_dir), "--matcher", "sequential"])
    assert code == 2 and "already exists; pass --overwrite" in err and err.count("\n") == 1
    assert (run_dir / COLMAP_DIR / POSES_JSON).read_bytes() == before
    code, _, err = cli(["colmap", str(run_dir), "--matcher", "sequential", "--overlap", "6", "--overwrite"])
    assert code == 0, err
    doc = json.loads((run_dir / COLMAP_DIR / POSES_JSON).read_text())
    assert doc["colmap"]["matcher"] == "sequential" and doc["colmap"]["overlap"] == 6
    assert doc["summary"]["registered"] >= 3
    assert not [p.name for p in run_dir.iterdir() if p.name.startswith(".")], "no staging folder left"


@pytest.mark.parametrize(
    "args, words",
    [
        (["--matcher", "vocab"], "allowed: exhaustive, sequential"),
        (["--intrinsics", "guess"], "allowed: known, estimated"),
        (["--overlap", "0"], "--overlap must be 1 or more"),
        (["--max-features", "10"], "--max-features must be 64 or more"),
    ],
)
def test_bad_options_exit_2_with_one_line(run_dir: Path, cli, tmp_path: Path, args, words) -> None:  # noqa: ANN001
    code, out, err = cli(["colmap", str(tmp_path), *args])  # (checked before the run is read)
    assert code == 2 and words in err and err.count("\n") == 1 and not out


def test_a_run_without_rgb_is_refused(tmp_path: Path, cli) -> None:  # noqa: ANN001
    run = small_run(tmp_path / "robots", renderer={"backend": "none"}, recon={"backend": "none"})
    code, _, err = cli(["colmap", str(run)])
    assert code == 2 and "no rendered frames" in err and err.count("\n") == 1
    assert not (run / COLMAP_DIR).exists()


def test_colmap_poses_need_agrisim_colmap_and_a_finished_run(tmp_path: Path, cli) -> None:  # noqa: ANN001
    run = small_run(tmp_path / "run", recon={"backend": "none"})
    code, _, err = cli(["recon", str(run), "--recon", "pointcloud", "--set", "recon.poses=colmap"])
    assert code == 2 and f"needs agrisim colmap {run} first" in err and err.count("\n") == 1
    assert not (run / "metrics.json").exists()
    code, _, err = cli(["run", "--set", "recon.poses=colmap", "--out", str(tmp_path / "new")])
    assert code == 2 and "needs the finished run" in err and err.count("\n") == 1
    assert not (tmp_path / "new").exists()
