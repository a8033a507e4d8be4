"""--resume: an interrupted run continued ends with the same files as an uninterrupted one.

The uninterrupted run of :data:`ARGS` is made once for the module (``whole``); each test that
continues a run cuts a copy of it short (:func:`_cut`), as a run stopped after a few frames
leaves it, and resumes that copy."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from agrisim.app.cli import main
from agrisim.config import build_config
from agrisim.episode import Episode

ARGS = {
    "plant": "coltsfoot",
    "render": {"shadow_samples": 2},
    "physics": {"backend": "kinematic"},
    "routine": {"setpoints": "1x3"},
    "camera": {"resolution": "160x90"},
}


def _run(out: Path) -> None:
    Episode(build_config(ARGS, {"output": {"out": str(out), "no_rrd": True}})).run()


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*.png"))}


def _interrupt(out: Path, keep: int) -> list[str]:
    """Make ``out`` look like a run stopped after ``keep`` frames: later frames' files gone,
    run.json saying interrupted, and no final reconstruction (metrics.json, clouds/), which only
    a finished run has."""
    doc = json.loads((out / "run.json").read_text())
    frames = sorted(doc["frames_complete"])
    lost = frames[keep:]
    for frame in lost:
        for png in out.rglob(f"{frame}.png"):
            png.unlink()
    (out / "metrics.json").unlink(missing_ok=True)
    shutil.rmtree(out / "clouds", ignore_errors=True)
    doc["status"] = "interrupted"
    doc["frames_complete"] = frames[:keep]
    doc["results"] = doc["results"][:keep]
    (out / "run.json").write_text(json.dumps(doc))
    return lost


def _cut(whole: Path, out: Path, keep: int) -> list[str]:
    """A copy of the uninterrupted run ``whole`` at ``out``, stopped after ``keep`` frames
    (:func:`_interrupt`): the frames lost."""
    shutil.copytree(whole, out)
    return _interrupt(out, keep)


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The uninterrupted run of ARGS, made once: tests only read it (and cut copies of it)."""
    out = tmp_path_factory.mktemp("resume") / "whole"
    _run(out)
    return out


def test_resume_gives_the_uninterrupted_files(whole, tmp_path, capsys):
    lost = _cut(whole, tmp_path / "cut", keep=2)
    assert lost and not any((tmp_path / "cut" / "rgb" / f"{f}.png").exists() for f in lost)
    kept = {f: (tmp_path / "cut" / "rgb" / f).stat().st_mtime_ns for f in ("r1_000.png",)}

    assert main(["run", "--resume", "--out", str(tmp_path / "cut"), "--no-rrd"]) == 0
    assert _files(tmp_path / "cut") == _files(whole)
    # frames complete before the interruption were not written again
    assert (tmp_path / "cut" / "rgb" / "r1_000.png").stat().st_mtime_ns == kept["r1_000.png"]
    uninterrupted = json.loads((whole / "run.json").read_text())
    cut = json.loads((tmp_path / "cut" / "run.json").read_text())
    assert cut["status"] == "complete"
    assert cut["frames_complete"] == uninterrupted["frames_complete"]
    for a, b in zip(uninterrupted["results"], cut["results"], strict=True):
        assert (a["frame"], a["reached"], a["ee_error_mm"], a["sim_time"]) == (
            b["frame"],
            b["reached"],
            b["ee_error_mm"],
            b["sim_time"],
        )
    assert json.loads((tmp_path / "cut" / "cameras.json").read_text()) == json.loads(
        (whole / "cameras.json").read_text()
    )


def test_a_resumed_run_with_a_depth_sensor_reads_its_measurements_back(tmp_path, capsys):
    """The frames complete before keep their depth_sensor/ and the reconstruction fuses them
    read back: the same files, clouds and metrics as an uninterrupted run (the noise is seeded
    by the view)."""
    sensed = {"sensor": {"backend": "azure-kinect-nfov"}}
    Episode(build_config(ARGS, sensed, {"output": {"out": str(tmp_path / "whole"), "no_rrd": True}})).run()
    _cut(tmp_path / "whole", tmp_path / "cut", keep=2)
    assert (tmp_path / "cut" / "depth_sensor" / "r1_000.png").exists()
    assert main(["run", "--resume", "--out", str(tmp_path / "cut"), "--no-rrd"]) == 0
    assert _files(tmp_path / "cut") == _files(tmp_path / "whole")
    assert any("depth_sensor" in f for f in _files(tmp_path / "whole"))
    for name in ("clouds/plant.ply", "metrics.json"):
        whole, cut = (tmp_path / run / name for run in ("whole", "cut"))
        if name.endswith(".json"):
            assert json.loads(cut.read_text())["labels"] == json.loads(whole.read_text())["labels"]
        else:
            assert cut.read_bytes() == whole.read_bytes()


def test_a_resumed_run_with_an_imager_goes_on_from_its_exposures(tmp_path, capsys):
    """The auto-exposure carries from view to view: a resumed run takes it up from the last
    frame of each arm on disk (cameras.json's exposure), so the remaining frames' noise and
    exposure, raw frames included, are the uninterrupted run's."""
    imaged = {"imager": {"model": "imx708", "raw": True}}
    Episode(build_config(ARGS, imaged, {"output": {"out": str(tmp_path / "whole"), "no_rrd": True}})).run()
    lost = _cut(tmp_path / "whole", tmp_path / "cut", keep=2)
    assert "r1_002" in lost  # resumed from r1_001's exposure
    assert main(["run", "--resume", "--out", str(tmp_path / "cut"), "--no-rrd"]) == 0
    assert _files(tmp_path / "cut") == _files(tmp_path / "whole")
    assert any(f.startswith("raw/") for f in _files(tmp_path / "whole"))
    cameras = [json.loads((tmp_path / run / "cameras.json").read_text()) for run in ("whole", "cut")]
    assert cameras[0] == cameras[1] and all("exposure" in f for f in cameras[0]["frames"].values())


def test_a_complete_run_is_not_resumed(whole, tmp_path, capsys):
    shutil.copytree(whole, tmp_path / "done")
    with pytest.raises(SystemExit) as exc:
        main(["run", "--resume", "--out", str(tmp_path / "done")])
    assert exc.value.code == 2
    assert "complete; nothing to continue" in capsys.readouterr().err


#: the command line that makes the run ARGS describes
CLI = [
    "run",
    "--plant",
    "coltsfoot",
    "--shadow-samples",
    "2",
    "--physics",
    "kinematic",
    "--setpoints",
    "1x3",
    "--resolution",
    "160x90",
    "--no-rrd",
]


def test_the_same_command_with_resume_appended_continues(whole, tmp_path, capsys):
    """People re-run the command they ran, with --resume: equal settings continue the run."""
    _cut(whole, tmp_path / "cut", keep=2)
    assert main([*CLI, "--out", str(tmp_path / "cut"), "--resume"]) == 0
    assert _files(tmp_path / "cut") == _files(whole)


@pytest.mark.parametrize(
    "change, key",
    [
        (["--plant", "boxwood"], "plant = 'coltsfoot'"),
        (["--resolution", "320x180"], "camera.resolution = '160x90'"),
        (["--set", "render.shadow_samples=3"], "renderer.raycast.shadow_samples = 2"),
    ],
)
def test_resume_refuses_a_setting_that_differs_and_names_it(whole, tmp_path, capsys, change, key):
    _cut(whole, tmp_path / "cut", keep=1)
    before = json.loads((tmp_path / "cut" / "run.json").read_text())
    with pytest.raises(SystemExit) as exc:
        main([*CLI, "--out", str(tmp_path / "cut"), "--resume", *change])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and key in err, err
    assert json.loads((tmp_path / "cut" / "run.json").read_text()) == before  # nothing touched
