"""Nothing lost: a killed run resumes to the files of an uninterrupted one, Ctrl-C leaves a
consistent ``interrupted`` run, and a failing plugin is named while finished frames stay."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from agrisim import BackendSpec, hookimpl
from agrisim.app.cli import main
from agrisim.config import build_config
from agrisim.episode import Episode
from agrisim.errors import BackendFailure
from agrisim.interfaces import Renderer
from agrisim.registry import make_plugin_manager

RUN = [
    "--plant",
    "coltsfoot",
    "--physics",
    "kinematic",
    "--setpoints",
    "1x3",
    "--resolution",
    "320x180",
    "--no-rrd",
    "--set",
    "metrics.truth_samples=50000",
]
#: files whose bytes legitimately differ between runs (times, the command line)
VOLATILE = {"run.json"}


def _default_sigint() -> None:
    # A run started from a terminal has Ctrl-C's default disposition; a test started by a
    # non-interactive shell's background job inherits SIGINT ignored and must not pass that on.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _agrisim(*args: str, **env: str) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", **env}
    return subprocess.Popen(
        [sys.executable, "-m", "agrisim", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        preexec_fn=_default_sigint,
    )


#: A plugin that sends its own process KILL_SIGNAL (SIGKILL unless named) when capture
#: number KILL_AFTER_CAPTURES + 1 is announced: the signal lands mid-run at a chosen frame,
#: however fast or loaded the machine. One sent from outside cannot: frames render faster than
#: the writer thread stores them, so by the time a poller sees two stored, all may be rendered.
KILLER = """
import os, signal
from agrisim import hookimpl

captures = 0

@hookimpl(tryfirst=True)  # before the dataset writer sees this capture
def agrisim_capture(run, capture):
    global captures
    captures += 1
    if captures > int(os.environ["KILL_AFTER_CAPTURES"]):
        os.kill(os.getpid(), getattr(signal, os.environ.get("KILL_SIGNAL", "SIGKILL")))
"""


def _killer_site(root: Path) -> Path:
    """A folder holding the killer as an installed distribution (a dist-info with its entry
    point), to put on PYTHONPATH."""
    info = root / "agrisim_test_killer-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: agrisim-test-killer\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[agrisim]\ntest-killer = agrisim_test_killer\n")
    (root / "agrisim_test_killer.py").write_text(KILLER)
    return root


def _complete_frames(out: Path) -> list[str]:
    try:
        return json.loads((out / "run.json").read_text()).get("frames_complete") or []
    except (OSError, ValueError):
        return []  # not written yet


def _wait_for_frames(proc: subprocess.Popen[bytes], out: Path, count: int, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while len(_complete_frames(out)) < count:
        assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else "exited"
        assert time.monotonic() < deadline, "the run made no progress"
        time.sleep(0.01)


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _comparable_run_json(out: Path) -> dict:
    doc = json.loads((out / "run.json").read_text())
    for row in doc["results"]:
        for key in ("ik_s", "plan_s"):  # wall-clock seconds
            row.pop(key)
    doc["config"].pop("output")  # where it went, and --resume itself
    return {k: doc[k] for k in ("status", "config", "seed", "labels", "frames_complete", "results")}


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An uninterrupted run, in a process of its own as the killed one is."""
    out = tmp_path_factory.mktemp("reference") / "run"
    proc = _agrisim("run", *RUN, "--out", str(out))
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err.decode()
    return out


def test_sigkill_at_a_random_frame_then_resume_gives_the_same_files(reference: Path, tmp_path: Path) -> None:
    total = len(_complete_frames(reference))
    assert total == 6
    seed = random.randrange(1 << 30)
    kill_after = random.Random(seed).randint(1, total - 1)
    out = tmp_path / "run"
    site = str(_killer_site(tmp_path / "site"))
    pythonpath = os.pathsep.join(p for p in (site, os.environ.get("PYTHONPATH", "")) if p)
    proc = _agrisim("run", *RUN, "--out", str(out), PYTHONPATH=pythonpath, KILL_AFTER_CAPTURES=str(kill_after))
    proc.wait(timeout=300)
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode() if proc.stderr else proc.returncode
    killed_with = _complete_frames(out)
    assert json.loads((out / "run.json").read_text())["status"] == "running", "a killed run cannot say more"
    assert len(killed_with) <= kill_after < total, f"seed {seed}: {killed_with}"

    resumed = _agrisim("run", "--resume", "--out", str(out))
    _, err = resumed.communicate(timeout=300)
    assert resumed.returncode == 0, err.decode()

    ours, theirs = _files(out), _files(reference)
    assert sorted(ours) == sorted(theirs), f"seed {seed}, killed after {killed_with}"
    differ = [name for name in ours if name not in VOLATILE and ours[name] != theirs[name]]
    assert not differ, f"seed {seed}, killed after {killed_with}: {differ}"
    assert _comparable_run_json(out) == _comparable_run_json(reference)
    assert {"metrics.json", "clouds/all.ply", "transforms.json", "cameras.json"} <= set(ours)


def test_sigint_stops_the_run_and_leaves_an_interrupted_run(tmp_path: Path) -> None:
    out = tmp_path / "run"
    site = str(_killer_site(tmp_path / "site"))
    pythonpath = os.pathsep.join(p for p in (site, os.environ.get("PYTHONPATH", "")) if p)
    # Ctrl-C as the fourth of twelve frames is captured: the three before it are kept, no more
    proc = _agrisim(
        "run",
        *RUN,
        "--setpoints",
        "2x3",
        "--resolution",
        "640x360",
        "--out",
        str(out),
        PYTHONPATH=pythonpath,
        KILL_AFTER_CAPTURES="3",
        KILL_SIGNAL="SIGINT",
    )
    # The timeout is a liveness bound only: how soon the run stops (about 0.3 s) is measured by
    # bench/interrupt_latency.py, since a loaded machine can take seconds.
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err.decode()
    assert err.decode().strip().endswith("interrupted")
    doc = json.loads((out / "run.json").read_text())
    assert doc["status"] == "interrupted"
    frames = doc["frames_complete"]
    # captures come setpoint by setpoint, each arm in turn: the first three are r1's and r2's
    # first and r1's second
    assert sorted(frames) == sorted([f"{arm}_{k:03d}" for k in range(2) for arm in ("r1", "r2")][:3])
    for frame in frames:
        for folder in ("rgb", "labels", "labels_vis", "depth"):
            with Image.open(out / folder / f"{frame}.png") as im:
                im.load()  # complete and decodable
    cams = json.loads((out / "cameras.json").read_text())
    assert sorted(cams["frames"]) == sorted(frames)
    assert not [p for p in out.rglob(".*") if p.is_file()], "no temporary files left"
    assert not (out / "metrics.json").exists(), "an interrupted run has no final reconstruction"


# ------------------------------------------------------------------- a failing plugin


class Exploding(Renderer):
    """Renders two frames, then raises: a third-party renderer with a bug."""

    calls = 0

    def render(self, camera, world_T_camera, link_poses):
        Exploding.calls += 1
        if Exploding.calls > 2:
            raise ZeroDivisionError("division by zero in the shader")
        from agrisim.interfaces import Frame

        h, w = camera.height, camera.width
        labels = np.zeros((h, w), np.uint8)
        labels[h // 3 : h // 2, w // 3 : w // 2] = 1
        depth = np.where(labels > 0, 0.5, 0.0).astype(np.float32)
        return Frame(np.full((h, w, 3), 90, np.uint8), labels, depth)


class ExplodingPlugin:
    @hookimpl
    def agrisim_renderers(self):
        return [BackendSpec(name="exploding", factory=Exploding, description="fails on its third frame")]


def _pm_with_exploding():
    pm = make_plugin_manager()
    pm.register(ExplodingPlugin(), name="exploding-plugin")
    return pm


def test_a_failing_plugin_is_named_and_finished_frames_stay(tmp_path: Path, monkeypatch, capsys) -> None:
    Exploding.calls = 0
    monkeypatch.setattr("agrisim.episode.make_plugin_manager", _pm_with_exploding)
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as exc:
        main(["run", *RUN, "--renderer", "exploding", "--out", str(out)])
    assert exc.value.code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "renderer backend 'exploding'" in err and "ZeroDivisionError" in err and "r1_001" in err
    doc = json.loads((out / "run.json").read_text())
    assert doc["status"] == "failed" and "exploding" in doc["summary"]["error"]
    assert sorted(doc["frames_complete"]) == ["r1_000", "r2_000"]
    for frame in doc["frames_complete"]:
        assert np.array(Image.open(out / "labels" / f"{frame}.png")).max() == 1


def test_backend_failure_from_the_api(tmp_path: Path) -> None:
    Exploding.calls = 0
    config = build_config(
        {
            "plant": "coltsfoot",
            "renderer": {"backend": "exploding"},
            "physics": {"backend": "kinematic"},
            "routine": {"setpoints": "1x3"},
            "camera": {"resolution": "64x36"},
            "output": {"out": str(tmp_path / "run"), "no_rrd": True},
        }
    )
    with pytest.raises(BackendFailure, match="renderer backend 'exploding'"):
        Episode(config, _pm_with_exploding()).run()
