"""A run through an imager (``--imager``): the RGB is the sensor's and the ISP's, developed from
the raw frame on disk; the labels and depth stay the renderer's exact ones."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from agrisim.app.cli import main
from agrisim.plugins.imagers.pipeline import IMAGERS, ImagePipeline

ARGS = ["--plant", "coltsfoot", "--physics", "kinematic", "--setpoints", "1x2", "--arms", "1", "--no-rrd"]
ARGS += ["--camera", "rpi-camera-3-wide", "--resolution", "192x108", "--shadow-samples", "4", "--recon", "none"]


def _png(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path))


def test_an_imaged_run_keeps_exact_labels_and_develops_its_raw_frames(tmp_path: Path, capsys) -> None:
    assert main(["run", *ARGS, "--out", str(tmp_path / "exact")]) == 0
    imaged = ["--imager", "imx708", "--jpeg-quality", "90", "--set", "imager.raw=true"]
    assert main(["run", *ARGS, *imaged, "--out", str(tmp_path / "imaged")]) == 0
    cameras = json.loads((tmp_path / "imaged" / "cameras.json").read_text())
    doc = cameras["imager"]
    assert doc["name"] == "imx708" and doc["bayer"] == "RGGB" and "assumed" in doc["sources"]
    run = json.loads((tmp_path / "imaged" / "run.json").read_text())
    assert run["backend_options"]["renderer"]["radiance"] is False  # as given: no radiance/ written
    assert not (tmp_path / "imaged" / "radiance").exists()
    pipe = ImagePipeline(IMAGERS["imx708"], jpeg_quality=90)
    for frame, entry in cameras["frames"].items():
        exact, imaged_dir = tmp_path / "exact", tmp_path / "imaged"
        for folder in ("labels", "depth", "instances"):
            assert np.array_equal(_png(exact / folder / f"{frame}.png"), _png(imaged_dir / folder / f"{frame}.png"))
        raw = _png(imaged_dir / "raw" / f"{frame}.png")
        assert raw.dtype == np.uint16 and raw.shape == (108, 192) and raw.max() <= 1023
        rgb = _png(imaged_dir / "rgb" / f"{frame}.png")
        assert np.array_equal(rgb, pipe.develop(raw))  # the RGB is the raw frame developed
        assert not np.array_equal(rgb, _png(exact / "rgb" / f"{frame}.png"))
        exposure = entry["exposure"]
        assert 100e-6 <= exposure["time_s"] <= 66.7e-3 and 1.0 <= exposure["analogue_gain"] <= 16.0
        assert abs(exposure["metered_luminance"] - 0.16) < 0.03  # the AE's target, nearly met


def test_agrisim_render_shoots_each_frame_again_at_its_recorded_exposure(tmp_path: Path, capsys) -> None:
    """Re-rendering an imaged run feeds the new radiance through the run's imager at the
    exposure each frame recorded, with the frame's own noise: with the same renderer the raw
    frames come out the run's, but for the few pixels where the saved scene's single-precision
    numbers (the run held double) move a photon count across a Poisson draw's step."""
    run = tmp_path / "run"
    imaged = ["--imager", "ov2740", "--set", "imager.raw=true", "--set", "imager.ae_frames=2"]
    assert main(["run", *ARGS, *imaged, "--out", str(run)]) == 0
    assert main(["render", str(run), "--renderer", "raycast", "--set", "renderer.raycast.shadow_samples=4"]) == 0
    again = tmp_path / "run-raycast"
    frames = sorted(p.name for p in (run / "rgb").glob("*.png"))
    assert frames and not (again / "radiance").exists()
    for name in frames:
        a, b = (_png(root / "raw" / name).astype(np.int32) for root in (run, again))
        same = a == b
        assert same.mean() > 0.99, f"{name}: {1 - same.mean():.2%} of the raw pixels differ"
        rgb_a, rgb_b = (_png(root / "rgb" / name).astype(np.int32) for root in (run, again))
        assert (rgb_a == rgb_b).all(axis=2).mean() > 0.95
