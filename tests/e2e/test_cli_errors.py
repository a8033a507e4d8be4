"""Bad input: exit status 2, exactly one line on stderr naming the problem, no traceback, and
nothing written or overwritten (DESIGN.md, "Errors").

The CLI runs in-process (``agrisim.app.cli.main``) for speed; two cases also run as real
subprocesses so that the actual stderr and exit status are checked.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import isolated_env

from agrisim.errors import UserError
from agrisim.robot.urdf import ur10_with_camera


def cuda_usable() -> bool:
    try:
        import drjit as dr
    except ImportError:
        return False
    return bool(dr.has_backend(dr.JitBackend.CUDA))


@pytest.fixture
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """tmp_path with the input files the cases refer to; the CLI runs from ``tmp_path/cwd`` so
    that a stray default output (``runs/...``) would be seen."""
    for var in list(os.environ):
        if var.startswith("AGRISIM_"):
            monkeypatch.delenv(var)
    (tmp_path / "broken.toml").write_text("[routine\nsetpoints = '1x1'\n")
    (tmp_path / "unknown_key.toml").write_text("[routine]\nsetpoints = '1x1'\nbogus = 1\n")
    (tmp_path / "rrd_both.toml").write_text("[output]\nrrd = 'x.rrd'\nno_rrd = true\n")
    (tmp_path / "afile").write_text("a regular file\n")
    (tmp_path / "garbage.glb").write_bytes(b"this is not a glTF file at all")
    head = "ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
    (tmp_path / "empty.ply").write_text(head.format(n=0) + "end_header\n")
    (tmp_path / "nan.ply").write_text(head.format(n=2) + "end_header\n0 0 0\n0 nan 0.1\n")
    (tmp_path / "good.ply").write_text(head.format(n=2) + "end_header\n0 0 0\n0 0 0.1\n")
    (tmp_path / "label300.ply").write_text(head.format(n=2) + "property int label\nend_header\n0 0 0 1\n0 0 0.1 300\n")
    (tmp_path / "label250.ply").write_text(head.format(n=2) + "property int label\nend_header\n0 0 0 1\n0 0 0.1 250\n")
    (tmp_path / "names.toml").write_text('[plant_file]\nlabel_names = {"1" = "leaf", "2" = "stem"}\n')
    calibration = "image_width: 320\nimage_height: 180\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{K}]\n"
    calibration += "distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [{D}]\n"
    K = "150, 0, 159.5, 0, 150, 89.5, 0, 0, 1"
    (tmp_path / "lens.yaml").write_text(calibration.format(K=K, D="-0.25, 0.06, 0.001, -0.001, -0.005"))
    (tmp_path / "folding.yaml").write_text(calibration.format(K=K, D="-0.6, 0.1, 0, 0, 0"))
    (tmp_path / "rational.yaml").write_text(calibration.format(K=K, D="-0.2, 0.05, 0, 0, 0, 0.1, 0, 0"))
    (tmp_path / "no_k.yaml").write_text("image_width: 320\nimage_height: 180\n")
    (tmp_path / "unparsable.yaml").write_text("image_width: [320, 180\ncamera_matrix: {")
    (tmp_path / "existing").mkdir()
    (tmp_path / "existing" / "keep.txt").write_text("precious results\n")
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    return tmp_path


def snapshot(root: Path) -> dict[str, tuple[bytes | None, int]]:
    """Every path under ``root`` with its contents and mtime (directories: None)."""
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None, p.stat().st_mtime_ns)
        for p in sorted(root.rglob("*"))
    }


def assert_one_line_error(code: int, err: str, expected: list[str]) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and err.endswith("\n"), f"not exactly one line: {err!r}"
    assert err.startswith("agrisim: error: "), err
    assert "Traceback" not in err
    for fragment in expected:
        assert fragment in err, f"{fragment!r} not in {err!r}"


# arguments after `run` and fragments the message must contain; {tmp} is the work dir. Cases
# that don't choose a physics backend get the light `kinematic` one (its options aren't
# touched), except where the default backend's options are the point.
CASES = [
    pytest.param(["--physics", "nope"], ["physics", "'nope'", "kinematic", "pybullet"], id="unknown-physics"),
    pytest.param(["--planner", "nope"], ["planner", "'nope'", "direct", "ompl"], id="unknown-planner"),
    pytest.param(["--rig", "nope"], ["rig", "'nope'", "paper"], id="unknown-rig"),
    pytest.param(["--camera", "nope"], ["camera", "'nope'", "rpi3-wide-1080p"], id="unknown-camera"),
    pytest.param(["--config", "{tmp}/broken.toml"], ["malformed TOML", "broken.toml"], id="malformed-toml"),
    pytest.param(["--config", "{tmp}/missing.toml"], ["config file not found", "missing.toml"], id="missing-config"),
    pytest.param(["--config", "{tmp}/unknown_key.toml"], ["unknown setting", "routine.bogus"], id="unknown-config-key"),
    pytest.param(["--set", "nope=1"], ["unknown setting", "'nope'"], id="unknown-set-key"),
    pytest.param(["--set", "seed"], ["KEY=VALUE", "'seed'"], id="set-without-value"),
    pytest.param(["--setpoints", "0x10"], ["setpoints", "0x10", "between 1 and 100"], id="setpoints-zero"),
    pytest.param(["--setpoints", "five"], ["setpoints", "LxC"], id="setpoints-malformed"),
    pytest.param(
        ["--set", "motion.reach_tolerance_mm=-1"],
        ["motion.reach_tolerance_mm", "greater than 0"],
        id="negative-tolerance",
    ),
    pytest.param(["--seed", "-3"], ["seed", "-3"], id="negative-seed"),
    pytest.param(["--seed", "x"], ["--seed", "'x'"], id="seed-not-int"),
    pytest.param(["--resolution", "10x"], ["resolution", "10x", "WxH"], id="resolution-malformed"),
    pytest.param(["--resolution", "4x4"], ["resolution", "4x4"], id="resolution-too-small"),
    pytest.param(["--arms", "3"], ["cell.arms", "2"], id="three-arms"),
    pytest.param(["--setpoints-csv", "{tmp}/missing.csv"], ["setpoint CSV not found", "missing.csv"], id="missing-csv"),
    pytest.param(
        ["--planner", "ompl", "--set", "planner.ompl.algorithm=Nope"],
        ["OMPL", "'Nope'", "RRTConnect"],
        id="unknown-ompl-algorithm",
    ),
    pytest.param(
        ["--set", "planner.ompl.algorithm=Nope"],
        ["OMPL", "'Nope'", "RRTConnect"],
        id="unknown-ompl-algorithm-default-planner",
    ),
    pytest.param(
        ["--physics", "pybullet", "--set", "physics.pybullet.nope=1"],
        ["pybullet", "unknown setting 'nope'"],
        id="unknown-backend-option",
    ),
    pytest.param(
        ["--set", "physics.pybullet.nope=1"],
        ["pybullet", "unknown setting 'nope'"],
        id="unknown-backend-option-default-physics",
    ),
    pytest.param(
        ["--planner", "direct", "--set", "planner.direct=3"], ["'direct'", "table"], id="backend-options-not-a-table"
    ),
    pytest.param(["--rrd", "{tmp}/x.rrd", "--no-rrd"], ["--rrd", "--no-rrd"], id="rrd-and-no-rrd"),
    pytest.param(["--config", "{tmp}/rrd_both.toml"], ["--rrd", "--no-rrd"], id="rrd-and-no-rrd-in-config"),
    pytest.param(["--overwrite", "--resume"], ["--overwrite", "--resume"], id="overwrite-and-resume"),
    pytest.param(["--resume"], ["--resume"], id="resume-without-run"),
    pytest.param(["--nope"], ["--nope"], id="unknown-flag"),
    pytest.param(["--plant", "nope"], ["unknown plant 'nope'", "boxwood", ".glb"], id="unknown-species"),
    pytest.param(["--plant", "{tmp}/garbage.glb"], ["garbage.glb"], id="unreadable-asset"),
    pytest.param(["--plant", "{tmp}/missing.obj"], ["missing.obj"], id="missing-asset"),
    pytest.param(["--shadow-samples", "33"], ["raycast", "shadow_samples", "32"], id="shadow-samples-too-many"),
    pytest.param(["--shadow-samples", "-1"], ["raycast", "shadow_samples"], id="shadow-samples-negative"),
    pytest.param(
        ["--renderer", "pybullet", "--seg-mode", "repopa", "--shadow-samples", "2"],
        ["renderer backend 'pybullet'", "shadow_samples"],
        id="shadow-samples-are-raycasts-own",
    ),
    pytest.param(["--set", "sink.rerunn.spawn=true"], ["[sink.rerunn]", "rerun"], id="unknown-sink"),
    pytest.param(["--set", "sink.rerun.nope=1"], ["sink 'rerun'", "nope"], id="unknown-sink-option"),
    pytest.param(["--resolution", "0x0"], ["resolution", "0x0"], id="resolution-zero"),
    pytest.param(["--set", "plant_file.alpha_cutoff=1.5"], ["plant_file.alpha_cutoff", "1"], id="alpha-cutoff-above-1"),
    pytest.param(["--seg-mode", "paint"], ["--seg-mode", "texture", "repopa"], id="unknown-seg-mode"),
    pytest.param(
        ["--renderer", "mitsuba", "--set", "renderer.mitsuba.variant=optix"],
        ["renderer backend 'mitsuba'", "variant", "'auto', 'cuda' or 'llvm'"],
        id="mitsuba-unknown-variant",
    ),
    pytest.param(
        ["--renderer", "mitsuba", "--set", "renderer.mitsuba.variant=cuda"],
        ["variant 'cuda'", "NVIDIA GPU"],
        id="mitsuba-cuda-without-gpu",
        marks=pytest.mark.skipif(cuda_usable(), reason="a usable GPU is here"),
    ),
    pytest.param(
        ["--renderer", "mitsuba", "--set", "renderer.mitsuba.spp=0"], ["mitsuba", "spp", "1"], id="mitsuba-spp-0"
    ),
    pytest.param(
        ["--renderer", "mitsuba", "--set", "renderer.mitsuba.envmap={tmp}/missing.exr"],
        ["envmap", "missing.exr", "no such file"],
        id="mitsuba-envmap-missing",
    ),
    pytest.param(
        ["--renderer", "mitsuba", "--set", "renderer.mitsuba.envmap={tmp}/afile"],
        ["envmap", "afile", "not an image"],
        id="mitsuba-envmap-not-an-image",
    ),
    pytest.param(["--renderer", "nope"], ["renderer", "'nope'", "raycast"], id="unknown-renderer"),
    pytest.param(
        ["--renderer", "pybullet", "--seg-mode", "repopa", "--labels", "organs", "--plant", "hydrangea"],
        ["renderer backend 'pybullet'", "organ labels", "renderers that can: mitsuba, raycast"],
        id="pybullet-renderer-has-no-organs",
    ),
    pytest.param(
        ["--renderer", "pybullet"],
        ["renderer backend 'pybullet'", "segmentation mode 'texture'", "renderers that can: mitsuba, raycast"],
        id="pybullet-renderer-ignores-opacity",
    ),
    # point plants
    pytest.param(["--as-points", "0"], ["--as-points", ">= 1", "0"], id="as-points-zero"),
    pytest.param(["--as-points", "999999999"], ["--as-points", "at most 5,000,000"], id="as-points-absurd"),
    pytest.param(["--as-points", "100", "--point-size", "0"], ["--point-size", "> 0"], id="point-size-zero"),
    pytest.param(["--as-points", "100", "--point-size", "-0.002"], ["--point-size", "> 0"], id="point-size-negative"),
    pytest.param(["--as-points", "100", "--point-size", "nan"], ["--point-size", "finite"], id="point-size-nan"),
    pytest.param(["--as-points", "100", "--point-size", "inf"], ["--point-size", "finite"], id="point-size-inf"),
    pytest.param(["--point-size", "0.002"], ["--point-size", "point plants"], id="point-size-of-a-mesh"),
    pytest.param(
        ["--renderer", "pybullet", "--seg-mode", "repopa", "--as-points", "100"],
        ["renderer backend 'pybullet'", "point plants", "renderers that can: raycast"],
        id="renderer-without-points",
    ),
    pytest.param(["--plant", "{tmp}/empty.ply"], ["empty.ply", "no points"], id="cloud-without-points"),
    pytest.param(["--plant", "{tmp}/nan.ply"], ["nan.ply", "NaN or infinite"], id="cloud-with-nan"),
    pytest.param(["--plant", "{tmp}/label300.ply"], ["label300.ply", "300", "outside 0..255"], id="cloud-label-300"),
    pytest.param(
        ["--plant", "{tmp}/label250.ply"],
        ["label250.ply", "[250]", "default table", "label_names"],
        id="cloud-label-not-in-default-table",
    ),
    pytest.param(
        ["--plant", "{tmp}/label250.ply", "--config", "{tmp}/names.toml"],
        ["label250.ply", "[250]", "label_names does not name", "[0, 1, 2]"],
        id="cloud-label-not-in-label-names",
    ),
    pytest.param(["--plant", "{tmp}/missing.ply"], ["missing.ply"], id="missing-cloud"),
    pytest.param(
        ["--plant", "{tmp}/good.ply", "--as-points", "10"], ["already a point cloud"], id="as-points-of-a-cloud"
    ),
    pytest.param(["--depth-sensor", "kinect9"], ["kinect9", "azure-kinect-nfov", "exact"], id="unknown-depth-sensor"),
    pytest.param(
        ["--depth-sensor", "azure-kinect-nfov", "--set", "sensor.azure-kinect-nfov.mode=wfov-binned"],
        ["mode", "nfov-unbinned", "wfov-binned"],
        id="depth-sensor-mode-it-lacks",
    ),
    pytest.param(
        ["--depth-sensor", "azure-kinect-nfov", "--as-points", "5000"],
        ["azure-kinect-nfov", "cannot see point plants", "exact"],
        id="depth-sensor-on-points",
    ),
    pytest.param(
        ["--set", "recon.depth=sensed"], ["recon.depth", "sensor", "truth"], id="recon-depth-neither-sensor-nor-truth"
    ),
    pytest.param(
        ["--depth-sensor", "d435", "--set", "sensor.d435.resolution=1920x1080"],
        ["resolution", "848x480", "1920x1080"],
        id="stereo-resolution-it-lacks",
    ),
    pytest.param(
        ["--depth-sensor", "d405", "--set", "sensor.d405.max_depth_m=2"],
        ["d405", "0.0464-0.5 m at 848x480", "max_depth_m"],
        id="stereo-depth-range-it-lacks",
    ),
    pytest.param(["--camera", "rpi4-wide"], ["rpi4-wide", "rpi-camera-3-wide"], id="unknown-camera-preset"),
    pytest.param(
        ["--camera-calibration", "{tmp}/unparsable.yaml"],
        ["unparsable.yaml", "does not parse"],
        id="calibration-unparsable",
    ),
    pytest.param(
        ["--camera-calibration", "{tmp}/no_k.yaml"], ["no_k.yaml", "no camera_matrix"], id="calibration-without-k"
    ),
    pytest.param(
        ["--camera-calibration", "{tmp}/folding.yaml"], ["folds the image", "peaks at"], id="calibration-lens-folds"
    ),
    pytest.param(
        ["--camera-calibration", "{tmp}/rational.yaml"],
        ["rational", "allowed: 4 or 5"],
        id="calibration-rational-model",
    ),
    pytest.param(
        ["--camera-calibration", "{tmp}/lens.yaml", "--resolution", "640x360"],
        ["camera.calibration fixes the image size"],
        id="calibration-and-resolution",
    ),
    pytest.param(
        ["--camera-calibration", "{tmp}/lens.yaml", "--renderer", "pybullet"],
        ["pybullet", "through a lens's distortion", "raycast"],
        id="lens-with-a-pinhole-renderer",
    ),
    pytest.param(["--imager", "imx219"], ["unknown imager 'imx219'", "imx708, ov2740"], id="unknown-imager"),
    pytest.param(["--imager", "imx708", "--jpeg-quality", "101"], ["jpeg_quality", "100"], id="jpeg-quality-over"),
    pytest.param(
        ["--imager", "imx708", "--set", "imager.bit_depth=20"], ["imager.bit_depth", "16"], id="bit-depth-over"
    ),
    pytest.param(["--imager", "imx708", "--exposure", "fast"], ["--exposure 'fast'", "auto"], id="exposure-word"),
    pytest.param(
        ["--imager", "ov2740", "--exposure", "0.1"], ["'ov2740' exposes", "33.333 ms"], id="exposure-too-long"
    ),
    pytest.param(
        ["--imager", "imx708", "--exposure", "0.01", "--set", "imager.gain=32"],
        ["analogue gains 1-16", "not 32"],
        id="gain-it-lacks",
    ),
    pytest.param(
        ["--imager", "imx708", "--renderer", "pybullet"],
        ["pybullet", "linear radiance for an imager", "raycast"],
        id="imager-with-a-renderer-without-radiance",
    ),
]


@pytest.mark.parametrize(("args", "expected"), CASES)
def test_bad_input(args: list[str], expected: list[str], workdir: Path, cli) -> None:
    out = workdir / "out"
    before = snapshot(workdir)
    argv = ["run", *(a.format(tmp=workdir) for a in args)]
    if not any(a.startswith(("--physics", "physics.")) for a in argv[1:]):
        argv += ["--physics", "kinematic"]
    code, stdout, err = cli([*argv, "--out", str(out)])
    assert_one_line_error(code, err, expected)
    assert stdout == ""
    assert not out.exists()
    assert snapshot(workdir) == before, "something was written"


def _readonly_dir(workdir: Path) -> Path:
    ro = workdir / "readonly"
    ro.mkdir()
    ro.chmod(0o500)
    probe = ro / "probe"
    try:
        probe.mkdir()
    except PermissionError:
        return ro
    probe.rmdir()  # running as root: permissions don't stop us
    ro.chmod(0o700)
    ro.rmdir()
    return workdir / "afile"  # a regular file cannot hold a directory, even for root


@pytest.mark.parametrize("where", ["readonly-dir", "under-a-file"])
def test_unwritable_out(where: str, workdir: Path, cli) -> None:
    parent = _readonly_dir(workdir) if where == "readonly-dir" else workdir / "afile"
    out = parent / "run"
    before = snapshot(workdir)
    try:
        code, stdout, err = cli(["run", "--physics", "kinematic", "--renderer", "none", "--out", str(out)])
    finally:
        if parent.is_dir():
            parent.chmod(0o700)
    assert_one_line_error(code, err, ["--out", str(out), "not writable"])
    assert not out.exists()
    assert snapshot(workdir) == before


def test_out_is_a_file(workdir: Path, cli) -> None:
    before = snapshot(workdir)
    code, _, err = cli(["run", "--physics", "kinematic", "--renderer", "none", "--out", str(workdir / "afile")])
    assert_one_line_error(code, err, ["--out", "afile", "not a directory"])
    assert snapshot(workdir) == before


def test_existing_out_needs_overwrite(workdir: Path, cli) -> None:
    existing = workdir / "existing"
    before = snapshot(workdir)
    code, _, err = cli(
        ["run", "--physics", "kinematic", "--renderer", "none", "--setpoints", "1x1", "--out", str(existing)]
    )
    assert_one_line_error(code, err, ["--out", "already exists", "--overwrite"])
    assert snapshot(workdir) == before  # contents and mtimes untouched
    assert (existing / "keep.txt").read_text() == "precious results\n"


def test_existing_recording_needs_overwrite(workdir: Path, cli) -> None:
    """A recording outside the run directory is finished work too (the rerun sink's preflight)."""
    rrd = workdir / "old.rrd"
    rrd.write_bytes(b"an old recording")
    before = snapshot(workdir)
    args = ["run", "--physics", "kinematic", "--renderer", "none", "--setpoints", "1x1", "--rrd", str(rrd)]
    code, _, err = cli([*args, "--out", str(workdir / "new")])
    assert_one_line_error(code, err, ["--rrd", "old.rrd", "already exists", "--overwrite"])
    assert snapshot(workdir) == before
    code, out, _ = cli([*args, "--out", str(workdir / "new"), "--overwrite"])
    assert code == 0 and f"recording: {rrd}" in out
    assert rrd.read_bytes() != b"an old recording"


def test_missing_urdf_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="URDF not found: /nonexistent.urdf"):
        ur10_with_camera("/nonexistent.urdf")
    broken = tmp_path / "a" / "b" / "c" / "d" / "broken.urdf"
    broken.parent.mkdir(parents=True)
    broken.write_text("<robot name='x'")
    with pytest.raises(UserError, match="cannot read URDF"):
        ur10_with_camera(str(broken))


# ------------------------------------------------------------------ real subprocesses


def _subprocess(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = isolated_env()
    return subprocess.run(
        [sys.executable, "-m", "agrisim", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=60
    )


def test_subprocess_unknown_backend(workdir: Path) -> None:
    out = workdir / "out"
    before = snapshot(workdir)
    proc = _subprocess(["run", "--physics", "nope", "--out", str(out)], workdir / "cwd")
    assert_one_line_error(proc.returncode, proc.stderr, ["physics", "'nope'", "kinematic"])
    assert proc.stdout == ""
    assert not out.exists()
    assert snapshot(workdir) == before


def test_subprocess_existing_out(workdir: Path) -> None:
    before = snapshot(workdir)
    proc = _subprocess(
        ["run", "--physics", "kinematic", "--renderer", "none", "--out", str(workdir / "existing")], workdir / "cwd"
    )
    assert_one_line_error(proc.returncode, proc.stderr, ["already exists"])
    assert snapshot(workdir) == before


ROS_CASES = [
    pytest.param([], ["--ros"], id="ros-missing"),
    pytest.param(["--ros", "3"], ["--ros", "'3'", "'1', '2'"], id="ros-unknown"),
    pytest.param(
        ["--ros", "2", "--real-time-factor", "-1"], ["real time factor", "0 (unpaced) or a positive"], id="rtf"
    ),
    pytest.param(["--ros", "2", "--rate", "0"], ["bridge 'ros2'", "rate", "greater than 0"], id="rate-zero"),
    pytest.param(["--ros", "2", "--out", "{tmp}/existing"], ["existing", "--overwrite"], id="ros-existing-out"),
]


@pytest.mark.parametrize(("args", "expected"), ROS_CASES)
def test_bad_ros_input(args: list[str], expected: list[str], workdir: Path, cli) -> None:
    """``agrisim ros``'s own flags, refused before any middleware is reached or anything written."""
    before = snapshot(workdir)
    argv = ["ros", *(a.format(tmp=workdir) for a in args), "--renderer", "none", "--physics", "kinematic"]
    if "--out" not in argv:
        argv += ["--out", str(workdir / "out")]
    code, stdout, err = cli(argv)
    assert_one_line_error(code, err, expected)
    assert not (workdir / "out").exists()
    assert snapshot(workdir) == before, "something was written"
