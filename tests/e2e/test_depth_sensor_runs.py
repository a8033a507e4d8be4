"""Runs with a depth sensor: what the sensor measured is written beside the exact depth, with
its geometry, and is what the reconstruction fuses (so a real sensor's noise shows in the
metrics), the same way in the run and in ``agrisim recon``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import small_run
from PIL import Image

from agrisim.plugins.apps.recon import reconstruct_saved_run
from agrisim.plugins.sensors import tof

SENSOR = {"backend": "azure-kinect-nfov"}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("sensor")
    return {
        "exact": small_run(base / "exact", plant="boston_fern"),
        "tof": small_run(
            base / "tof", plant="boston_fern", sensor=SENSOR, output={"out": str(base / "tof"), "no_rrd": False}
        ),
    }


def test_the_sensor_depth_is_written_with_its_geometry(runs: dict[str, Path]) -> None:
    run, exact = runs["tof"], runs["exact"]
    cameras = json.loads((run / "cameras.json").read_text())
    sensor = cameras["sensor"]
    assert sensor["name"] == "azure-kinect-nfov"
    assert (sensor["intrinsics"]["width"], sensor["intrinsics"]["height"]) == (tof.WIDTH, tof.HEIGHT)
    R = np.asarray(sensor["camera_T_sensor"])[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert "sensor" not in json.loads((exact / "cameras.json").read_text())
    assert not (exact / "depth_sensor").exists()  # the exact sensor's measurement is depth/
    done = json.loads((run / "run.json").read_text())["frames_complete"]
    assert len(done) == 6  # 1x3 setpoints, two arms
    for frame in done:
        measured = np.asarray(Image.open(run / "depth_sensor" / f"{frame}.png"))
        truth = np.asarray(Image.open(run / "depth" / f"{frame}.png"))
        assert measured.dtype == np.uint16 and measured.shape == truth.shape
        both = (measured > 0) & (truth > 0)
        assert both.mean() > 0.3, "the sensor measured little of the colour camera's view"
        # a real sensor: not the truth, but within its noise of it on most pixels (edges fly)
        diff = np.abs(measured[both].astype(np.int64) - truth[both])
        assert (diff > 0).mean() > 0.5
        assert np.median(diff) < 3 * tof.RANDOM_ERROR_M * 1000


def test_the_reconstruction_fuses_the_sensor_depth(runs: dict[str, Path], tmp_path: Path) -> None:
    metrics = {name: json.loads((run / "metrics.json").read_text()) for name, run in runs.items()}
    assert metrics["tof"]["depth"] == "sensor:azure-kinect-nfov"
    assert metrics["exact"]["depth"] == "sensor:exact"
    plant = {name: m["labels"]["plant"] for name, m in metrics.items()}
    # noisy depth puts points off the true surface: fewer within 2 mm of it
    assert plant["tof"]["precision"]["2"] < plant["exact"]["precision"]["2"] - 0.1
    # agrisim recon reads depth_sensor/ back and gets the same; with recon.depth=truth, the truth's
    _, again = reconstruct_saved_run(runs["tof"], {}, out_dir=tmp_path / "again")
    assert again["depth"] == "sensor:azure-kinect-nfov"
    # (the same points; the truth is sampled again from the saved plant, so precision moves a hair)
    assert (again["labels"]["plant"]["points"], again["labels"]["plant"]["pixels"]) == (
        plant["tof"]["points"],
        plant["tof"]["pixels"],
    )
    for t, p in plant["tof"]["precision"].items():
        assert again["labels"]["plant"]["precision"][t] == pytest.approx(p, abs=1e-3)
    _, truth = reconstruct_saved_run(runs["tof"], {"recon": {"depth": "truth"}}, out_dir=tmp_path / "truth")
    assert truth["depth"] == "truth"
    assert truth["labels"]["plant"]["precision"]["2"] == pytest.approx(plant["exact"]["precision"]["2"], abs=0.02)


def test_the_recording_shows_the_sensor_depth_as_the_camera_depth(runs: dict[str, Path]) -> None:
    """``depth`` is what the sensor measured (as a robot's depth topic), ``depth_truth`` the
    exact depth: byte for byte the run's PNGs, in capture order."""
    from rerun.chunk import RrdReader

    run = runs["tof"]
    logged: dict[str, list[np.ndarray]] = {"depth": [], "depth_truth": []}
    for chunk in RrdReader(run / "recording.rrd").stream():
        kind = chunk.entity_path.lstrip("/").removeprefix("world/r1/camera/")
        if kind not in logged or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if "DepthImage:buffer" in batch.schema.names:
            for row in batch.column("DepthImage:buffer").to_pylist():
                logged[kind].append(np.asarray(row[0], np.uint8).view(np.uint16))
    frames = sorted(f.stem for f in (run / "depth_sensor").glob("r1_*.png"))
    for kind, folder in (("depth", "depth_sensor"), ("depth_truth", "depth")):
        pngs = [np.asarray(Image.open(run / folder / f"{f}.png")).ravel() for f in frames]
        assert len(logged[kind]) == len(pngs), kind
        for got, want in zip(logged[kind], pngs, strict=True):
            assert np.array_equal(got, want), kind


def test_the_bag_publishes_the_sensor_depth_as_the_camera_depth(runs: dict[str, Path], cli) -> None:  # noqa: ANN001
    """``agrisim export rosbag``: ``/A/camera/depth`` is the sensor's measurement and
    ``/A/camera/depth_truth`` the exact depth (REP 118 metres, +Inf for none), read back with
    ``mcap-ros2-support``."""
    from mcap_ros2.reader import read_ros2_messages

    run = runs["tof"]
    code, _, err = cli(["export", "rosbag", str(run)])
    assert code == 0, err
    frames = json.loads((run / "cameras.json").read_text())["frames"]
    seen = {"depth": 0, "depth_truth": 0}
    for m in read_ros2_messages(str(run / "rosbag" / "rosbag.mcap")):
        arm, _, kind = m.channel.topic.strip("/").partition("/camera/")
        if kind not in seen:
            continue
        msg = m.ros_msg
        frame = next(f for f, e in frames.items() if e["robot"] == arm and round(e["sim_time"] * 1e9) == m.log_time_ns)
        folder = "depth_sensor" if kind == "depth" else "depth"
        mm = np.asarray(Image.open(run / folder / f"{frame}.png"))
        depth = np.frombuffer(bytes(msg.data), "<f4").reshape(msg.height, msg.width)
        assert np.array_equal(np.isinf(depth), mm == 0), (kind, frame)
        assert np.array_equal(depth[mm > 0], mm[mm > 0].astype(np.float32) / np.float32(1000)), (kind, frame)
        seen[kind] += 1
    assert seen == {"depth": 6, "depth_truth": 6}
