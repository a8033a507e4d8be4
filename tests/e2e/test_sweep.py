"""``agrisim sweep``: a grid of tiny runs on one local Ray (two cores, and a custom resource
``fake_gpu`` of one unit standing in for a GPU), started once for the module.

One sweep of three cells runs once (module fixture): two of its cells are GPU runs, which
must take the one ``fake_gpu`` in turn, and the second of them loses its worker (``os._exit``)
after its third view on its first attempt, which Ray must retry and the retry resume. The
tests then read the run folders back against independent truth: a plain ``agrisim run`` of
the crashed cell, ``agrisim export coco`` of that run, the folders' own ``run.json``. A damaged
copy of the sweep is resumed. Bad input exits 2 with one line and writes nothing.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import local_ray
from PIL import Image

from agrisim.files import layout
from agrisim.plugins.apps.sweep import plan_sweep, read_spec
from agrisim.plugins.apps.sweep_run import run_cell_task, sweep

BASE = """\
physics.backend = "kinematic"
routine.setpoints = "1x3"
camera.resolution = "320x180"
metrics.truth_samples = 20000
[renderer.raycast]
shadow_samples = 0
"""
SPEC = BASE + '[axes]\npcg_seed = [1, 2, 3]\n"renderer.raycast.ambient" = [0.3]\n[sweep]\nafter = ["coco"]\n'
NAMES = ["pcg_seed=1,ambient=0.3", "pcg_seed=2,ambient=0.3", "pcg_seed=3,ambient=0.3"]
GPU_CELLS = (0, 1)
CRASHED = 1
IMAGE_FOLDERS = ("rgb", "labels", "depth")


@pytest.fixture(scope="module")
def ray_local() -> Iterator[None]:
    """One local Ray for the module: two CPUs and one ``fake_gpu``."""
    with local_ray(__name__, fake_gpu=1):
        yield


def logged_task(log: str, marker: str, crash: str) -> Callable[..., dict[str, Any]]:
    """:func:`run_cell_task`, with each attempt's start and end (time, Ray's resources) logged,
    and the cell ``crash``'s worker killed after its third view on its first attempt."""

    def task(config: Mapping[str, Any], after: Sequence[str], colmap: Mapping[str, Any]) -> dict[str, Any]:
        import ray

        name = Path(config["output"]["out"]).name
        resources = ray.get_runtime_context().get_assigned_resources()

        def note(event: str) -> None:
            with open(log, "a") as f:
                f.write(json.dumps({"cell": name, "event": event, "t": time.time(), "resources": resources}) + "\n")

        note("start")
        if name == crash and not Path(marker).exists():
            from agrisim.episode import Episode

            original = Episode._take_view
            views = []

            def take_view(self: Any, *args: Any, **kwargs: Any) -> Any:
                out = original(self, *args, **kwargs)
                views.append(1)
                if len(views) == 3:
                    Path(marker).write_text(str(os.getpid()))
                    note("end")
                    os._exit(1)  # the worker is lost, as to the OOM killer
                return out

            Episode._take_view = take_view  # type: ignore[method-assign]
        record = run_cell_task(config, after, colmap)
        note("end")
        return record

    return task


@pytest.fixture(scope="module")
def swept(ray_local: None, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The module's sweep: three cells, two on the fake GPU, one worker lost and retried."""
    root = tmp_path_factory.mktemp("sweep")
    (root / "spec.toml").write_text(SPEC)
    plan = plan_sweep(read_spec(root / "spec.toml"), out=root / "out")
    # (raycast's variant "auto" would take the fake GPU too: it stands in for CUDA)
    cells = tuple(replace(c, device="gpu" if i in GPU_CELLS else "cpu") for i, c in enumerate(plan.cells))
    plan = replace(plan, cells=cells)
    log, marker = root / "tasks.log", root / "crashed"
    task = logged_task(str(log), str(marker), NAMES[CRASHED])
    t0 = time.perf_counter()
    result = sweep(plan, gpu_resource="fake_gpu", task=task)
    events = [json.loads(line) for line in log.read_text().splitlines()]
    return {"root": root, "plan": plan, "result": result, "events": events, "marker": marker, "wall": t0}


def run_json(run_dir: Path) -> dict[str, Any]:
    return json.loads((run_dir / layout.RUN_JSON).read_text())


def images(run_dir: Path) -> dict[str, np.ndarray]:
    """Every image of the run's frames, decoded, by folder/file."""
    out = {}
    for folder in IMAGE_FOLDERS:
        for path in sorted((run_dir / folder).glob("*.png")):
            out[f"{folder}/{path.name}"] = np.asarray(Image.open(path))
    return out


def assert_same_images(a: Path, b: Path) -> None:
    ia, ib = images(a), images(b)
    assert ia.keys() == ib.keys() and len(ia) == 6 * len(IMAGE_FOLDERS)
    for key in ia:
        assert np.array_equal(ia[key], ib[key]), key


# ------------------------------------------------------------------------------- placement, retry


def test_gpu_runs_take_one_gpu_each_and_never_more_at_once_than_there_are(swept: dict[str, Any]) -> None:
    events = swept["events"]
    for e in events:
        expected = 1.0 if e["cell"] in (NAMES[i] for i in GPU_CELLS) else None
        assert e["resources"].get("fake_gpu") == expected, e
        assert e["resources"].get("CPU") == 1.0
    # every attempt (the lost one too) as an interval; GPU holders never overlap (one fake_gpu)
    starts = [e for e in events if e["event"] == "start"]
    ends = [e for e in events if e["event"] == "end"]
    assert len(starts) == len(ends) == len(NAMES) + 1  # the lost attempt, and its retry
    steps = sorted((e["t"], 1 if e["event"] == "start" else -1) for e in events if "fake_gpu" in e["resources"])
    holding = peak = 0
    for _, step in steps:  # (at equal times an end comes first)
        holding += step
        peak = max(peak, holding)
    assert peak == 1


def test_a_lost_worker_is_retried_and_its_run_resumed_not_redone(swept: dict[str, Any]) -> None:
    assert swept["marker"].is_file()  # the first attempt died
    starts = [e["cell"] for e in swept["events"] if e["event"] == "start"]
    assert starts.count(NAMES[CRASHED]) == 2 and all(starts.count(n) == 1 for n in NAMES if n != NAMES[CRASHED])
    runs = {r["name"]: r for r in swept["result"].runs}
    # the retry found the lost attempt's unfinished run and continued it (that a resumed run
    # keeps its saved views is test_resume_keeps_...'s: here the writer thread's progress at
    # the moment of death is not known)
    assert runs[NAMES[CRASHED]]["action"] == "resume"
    assert int(swept["marker"].read_text()) != runs[NAMES[CRASHED]]["pid"]
    for name in NAMES:  # every run complete, no view twice
        doc = run_json(swept["plan"].out / name)
        assert doc["status"] == "complete"
        frames = [r["frame"] for r in doc["results"]]
        assert len(frames) == len(set(frames)) == 6 and sorted(doc["frames_complete"]) == sorted(frames)


def test_a_cell_equals_a_plain_run_of_its_settings(swept: dict[str, Any], cli: Callable[..., Any]) -> None:
    """The crashed and resumed cell against ``agrisim run`` of the same settings, and its
    coco follow-up against ``agrisim export coco`` of that run."""
    root = swept["root"]
    (root / "base.toml").write_text(BASE)
    ref = root / "plain"
    code, _, err = cli(
        ["run", "--config", str(root / "base.toml"), "--pcg-seed", "2"]
        + ["--set", "renderer.raycast.ambient=0.3", "--no-rrd", "--out", str(ref)]
    )
    assert code == 0, err
    cell = swept["plan"].out / NAMES[CRASHED]
    assert_same_images(cell, ref)
    assert run_json(cell)["summary"]["metrics"] == run_json(ref)["summary"]["metrics"]
    code, _, err = cli(["export", "coco", str(ref)])
    assert code == 0, err
    coco = json.loads((cell / "coco" / "annotations.json").read_text())
    expected = json.loads((ref / "coco" / "annotations.json").read_text())
    assert coco["annotations"] == expected["annotations"] and coco["images"] == expected["images"]


# ------------------------------------------------------------------------------- the manifest


def test_the_manifest_lists_every_run_as_its_folder_holds_it(swept: dict[str, Any]) -> None:
    out = swept["plan"].out
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["status"] == "complete"
    assert sorted(p.name for p in out.iterdir()) == sorted([*NAMES, "sweep.json"])
    assert [r["name"] for r in doc["runs"]] == NAMES
    for i, r in enumerate(doc["runs"]):
        saved = run_json(out / r["run_dir"])
        assert r["settings"] == {"pcg_seed": i + 1, "renderer.raycast.ambient": 0.3}
        assert saved["config"]["pcg_seed"] == i + 1
        assert saved["config"]["renderer"]["raycast"]["ambient"] == 0.3
        assert r["status"] == "complete" and r["after"] == {"coco": "done"}
        assert r["views"] == len(saved["frames_complete"]) == 6
        assert r["metrics"] == saved["summary"]["metrics"] and r["metrics"]["plant"]["points"] > 0
        assert r["gpu"] == (i in GPU_CELLS)
        assert 0 < r["seconds"] <= doc["wall_s"]


# ------------------------------------------------------------------------------- resume


def _stat(root: Path) -> dict[str, tuple[bytes, int]]:
    return {str(p.relative_to(root)): (p.read_bytes(), p.stat().st_mtime_ns) for p in root.rglob("*") if p.is_file()}


def test_resume_keeps_complete_runs_and_continues_the_rest(
    swept: dict[str, Any], cli: Callable[..., Any], tmp_path: Path
) -> None:
    """A copy of the sweep as an interrupted one leaves it: one run complete, one unfinished
    (three of its six views saved), one never started; resumed, the complete run is not
    touched, the unfinished one keeps its views and renders the rest, and every image equals
    the uninterrupted sweep's."""
    source = swept["plan"].out
    out = tmp_path / "out"
    shutil.copytree(source, out)  # (copy2: contents and times)
    (tmp_path / "spec.toml").write_text(SPEC)
    kept, unfinished, missing = (out / n for n in NAMES)
    doc = run_json(unfinished)
    frames = sorted(doc["frames_complete"])
    doc.update(status="running", frames_complete=frames[:3])
    (unfinished / layout.RUN_JSON).write_text(json.dumps(doc))
    for frame in frames[3:]:
        for folder in IMAGE_FOLDERS:
            layout.image(unfinished, folder, frame).unlink()
    (unfinished / layout.METRICS_JSON).unlink()
    shutil.rmtree(unfinished / "coco")
    shutil.rmtree(missing)
    before_kept, before_unfinished = _stat(kept), _stat(unfinished)

    code, stdout, err = cli(["sweep", str(tmp_path / "spec.toml"), "--out", str(out), "--resume"])
    assert code == 0, err
    assert "1 of 3 runs complete already" in stdout
    assert _stat(kept) == before_kept  # not a byte, not a time
    after = _stat(unfinished)
    for frame in frames[:3]:
        for folder in IMAGE_FOLDERS:
            key = str(layout.image(unfinished, folder, frame).relative_to(unfinished))
            assert after[key] == before_unfinished[key]  # kept, not rendered again
    for name in NAMES:
        assert_same_images(out / name, source / name)
        assert run_json(out / name)["status"] == "complete"
    manifest = json.loads((out / "sweep.json").read_text())
    assert manifest["status"] == "complete"
    assert [r["action"] for r in manifest["runs"]] == ["skip", "resume", "run"]
    assert all(r["status"] == "complete" for r in manifest["runs"])


# ------------------------------------------------------------------------------- bad input


def _snapshot(root: Path) -> dict[str, tuple[bytes | None, int]]:
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None, p.stat().st_mtime_ns)
        for p in sorted(root.rglob("*"))
    }


BAD = [
    pytest.param(BASE + "[axes]\nbogus.key = [1, 2]\n", [], ["bogus"], id="unknown-axis"),
    pytest.param(BASE + '[axes]\nplant = ["boxwood", "nope"]\n', [], ["plant=nope", "'nope'"], id="unknown-plant"),
    pytest.param(
        BASE + '[axes]\n"renderer.raycast.shadow_samples" = [0, 99]\n',
        [],
        ["shadow_samples=99", "shadow_samples"],
        id="bad-value-in-a-later-cell",
    ),
    pytest.param(BASE + '[axes]\n"renderer.backend" = ["raycast", "nope"]\n', [], ["'nope'"], id="unknown-renderer"),
    pytest.param(BASE + "[axes]\nplant_seed = [1, -1]\n", [], ["plant_seed=-1", "seed"], id="bad-plant-seed"),
    pytest.param(BASE, [], ["grid is empty"], id="no-axes"),
    pytest.param(BASE + "[axes]\npcg_seed = []\n", [], ["grid is empty", "pcg_seed"], id="empty-axis"),
    pytest.param(BASE + "[axes]\npcg_seed = 3\n", [], ["list"], id="axis-not-a-list"),
    pytest.param(BASE + '[axes]\npcg_seed = [1]\n[sweep]\nafter = ["nope"]\n', [], ["'nope'", "coco"], id="after"),
    pytest.param(
        BASE + "[axes]\npcg_seed = [1]\n", ["--ray-address", "127.0.0.1:1"], ["127.0.0.1:1"], id="unreachable-ray"
    ),
    pytest.param(
        BASE + "[axes]\npcg_seed = [1]\n[sweep]\ngpu = true\n",
        ["--gpus", "2", "--gpu-resource", "fake_gpu"],
        ["--gpus 2", "1 fake_gpu"],
        id="more-gpus-than-exist",
    ),
    pytest.param(
        BASE + "[axes]\npcg_seed = [1]\n[sweep]\ngpu = true\n",
        ["--gpu-resource", "no_such_gpu"],
        ["no_such_gpu"],
        id="gpu-run-without-gpus",
    ),
    pytest.param(BASE + "[axes]\npcg_seed = [1]\n", ["--out", "{tmp}/existing"], ["already exists"], id="existing-out"),
    pytest.param(BASE + "[axes]\npcg_seed = [1]\n", ["--resume"], ["sweep.json"], id="resume-no-sweep"),
]


@pytest.mark.parametrize(("spec", "flags", "expected"), BAD)
def test_bad_input_exits_2_with_one_line_and_writes_nothing(
    spec: str,
    flags: list[str],
    expected: list[str],
    ray_local: None,
    cli: Callable[..., Any],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    (tmp_path / "spec.toml").write_text(spec)
    (tmp_path / "existing").mkdir()
    (tmp_path / "existing" / "keep.txt").write_text("precious\n")
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    flags = [f.format(tmp=tmp_path) for f in flags]
    if "--out" not in flags:
        flags += ["--out", str(tmp_path / "out")]
    before = _snapshot(tmp_path)
    code, _, err = cli(["sweep", str(tmp_path / "spec.toml"), *flags])
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("agrisim: error: ") and "Traceback" not in err, err
    for fragment in expected:
        assert fragment in err, f"{fragment!r} not in {err!r}"
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("name", ["seeds", "gpus"])
def test_the_example_specs_plan_as_their_comments_say(name: str, tmp_path: Path) -> None:
    """The README's example sweeps: every cell checked as a run would check it (the species'
    ``seed`` too, which the seeds example varies), the grid the product of the axes, and the
    GPU example's runs each holding a GPU."""
    import math

    from agrisim.config import load_toml

    path = Path(__file__).resolve().parents[2] / "examples" / "sweeps" / f"{name}.toml"
    axes = load_toml(path)["axes"]
    plan = plan_sweep(read_spec(path), out=tmp_path / "out")
    assert len(plan.cells) == math.prod(len(v) for v in axes.values())
    assert len({c.name for c in plan.cells}) == len(plan.cells)
    # seeds: raycast's variant auto, a GPU where the cluster has one; gpus: Mitsuba's cuda
    assert {c.device for c in plan.cells} == {"gpu" if name == "gpus" else "auto"}
    assert not (tmp_path / "out").exists()  # planning writes nothing
