"""``agrisim render``: a finished run's RGB drawn again from what the run saved.

Truth: ``agrisim run --renderer mitsuba`` itself (a re-render with the same settings must give
its bytes), the source run's files (carried over unchanged), and an interpreter in which Open3D,
pybullet, Pinocchio, OMPL and Rerun cannot be imported.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import isolated_env, local_ray

from agrisim.config import build_config
from agrisim.episode import Episode
from agrisim.errors import ConfigError
from agrisim.files import layout
from agrisim.plugins.render.mitsuba.variant import resolve_variant

try:
    resolve_variant("llvm")
except ConfigError:  # pragma: no cover - setup.sh installs libLLVM
    pytest.skip("Mitsuba's LLVM variant is not usable here", allow_module_level=True)

MITSUBA = {"variant": "llvm", "spp": 4}
#: what the re-render must do without (agrisim render's promise of a minimal install)
HEAVY = ("open3d", "pybullet", "pybullet_data", "pinocchio", "ompl", "rerun", "coal", "ray", "trimesh")


def small_run(out: Path, renderer: str) -> Path:
    config = build_config(
        {
            "plant": "indian_cress",
            "renderer": {"backend": renderer, "mitsuba": MITSUBA},
            "physics": {"backend": "kinematic"},
            "routine": {"setpoints": "1x3"},
            "camera": {"resolution": "96x54"},
            "recon": {"backend": "none"},
            "output": {"out": str(out), "no_rrd": True},
        }
    )
    _, summary = Episode(config).run()
    assert summary.status == "complete" and summary.reached >= 4
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same small run rendered by raycast and by mitsuba."""
    root = tmp_path_factory.mktemp("render")
    return {name: small_run(root / name, name) for name in ("raycast", "mitsuba")}


def files(root: Path, folder: str) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((root / folder).glob("*.png"))}


def rerender(run_dir: Path, *args: str, blocked: tuple[str, ...] = HEAVY) -> subprocess.CompletedProcess[str]:
    """``agrisim render`` in a fresh interpreter where ``blocked`` modules cannot be imported."""
    code = (
        "import sys\n"
        f"for m in {blocked!r}: sys.modules[m] = None\n"
        "from agrisim.app.cli import main\n"
        f"sys.exit(main({['render', str(run_dir), *args]!r}))\n"
    )
    env = isolated_env()
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)


def sets() -> list[str]:
    return [arg for k, v in MITSUBA.items() for arg in ("--set", f"renderer.mitsuba.{k}={v}")]


@pytest.fixture(scope="module")
def rerendered(runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str, str, int]:
    """The raycast run re-rendered by mitsuba in an interpreter without Open3D, pybullet,
    Pinocchio, OMPL or Rerun, the source holding files made from its old RGB (COLMAP's model,
    a bag) meanwhile: (its folder, stdout, stderr, exit status). Tests read it, and copy it
    before changing it."""
    out = tmp_path_factory.mktemp("rerendered") / "re"
    made_from_rgb = [runs["raycast"] / layout.COLMAP / "poses.json", runs["raycast"] / layout.ROSBAG / "metadata.yaml"]
    for path in made_from_rgb:
        path.parent.mkdir()
        path.write_text("{}")
    try:
        done = rerender(runs["raycast"], "--out", str(out), *sets())
    finally:
        for path in made_from_rgb:
            shutil.rmtree(path.parent)
    return out, done.stdout, done.stderr, done.returncode


def test_rerender_equals_a_mitsuba_run_without_the_heavy_stack(
    runs: dict[str, Path], rerendered: tuple[Path, str, str, int]
) -> None:
    """The raycast run re-rendered by mitsuba without the heavy stack: its RGB is byte for byte
    the mitsuba run's, its labels and depth the source's (which are mitsuba's too), and every
    other file is carried over but those made from the old RGB (COLMAP's model of it, the bag
    holding it)."""
    out, stdout, stderr, status = rerendered
    assert status == 0, stderr
    assert "re-rendered" in stdout
    assert not (out / layout.COLMAP).exists() and not (out / layout.ROSBAG).exists()
    assert files(out, "rgb") == files(runs["mitsuba"], "rgb")
    assert files(out, "rgb") != files(runs["raycast"], "rgb")
    for folder in ("labels", "depth", "instances", "labels_vis"):
        assert files(out, folder) == files(runs["raycast"], folder) == files(runs["mitsuba"], folder)
    for name in (layout.RUN_JSON, layout.CAMERAS_JSON, str(layout.SCENE_GLB)):
        assert (out / name).read_bytes() == (runs["raycast"] / name).read_bytes()
    record = json.loads((out / "render.json").read_text())
    assert record["status"] == "complete" and record["renderer"] == "mitsuba"
    assert sorted(record["frames_done"]) == sorted(p.stem for p in (out / "rgb").glob("*.png"))


def test_a_mitsuba_run_redrawn_by_raycast_is_the_raycast_run(runs: dict[str, Path], tmp_path: Path) -> None:
    """The other way round: the mitsuba run re-rendered by raycast (the arms drawn from the
    saved scene, not the robot cell) gives the raycast run's RGB, but for a pixel or two one
    level off: the saved scene holds glTF's single-precision numbers where the run held double."""
    import numpy as np
    from PIL import Image

    out = tmp_path / "re"
    done = rerender(runs["mitsuba"], "--renderer", "raycast", "--out", str(out))
    assert done.returncode == 0, done.stderr
    frames = sorted(files(runs["raycast"], "rgb"))
    assert sorted(files(out, "rgb")) == frames
    differing = 0
    for name in frames:
        a, b = (np.asarray(Image.open(root / "rgb" / name), np.int16) for root in (out, runs["raycast"]))
        assert np.abs(a - b).max() <= 1
        differing += int((a != b).any(axis=2).sum())
    assert differing <= 0.001 * len(frames) * a.shape[0] * a.shape[1]
    mitsuba = np.asarray(Image.open(runs["mitsuba"] / "rgb" / frames[0]), np.int16)
    assert np.abs(np.asarray(Image.open(out / "rgb" / frames[0]), np.int16) - mitsuba).max() > 10


def test_radiance_is_what_the_rgb_encodes(runs: dict[str, Path], tmp_path: Path) -> None:
    """``renderer.mitsuba.radiance``: every frame gets radiance/<frame>.exr, which a second
    reader (Mitsuba's Bitmap) reads as float RGB, and which encodes to the frame's PNG byte for
    byte; the RGB is the same as without it."""
    import mitsuba as mi
    import numpy as np
    from PIL import Image

    from agrisim.scene.colour import encode_srgb8

    out = tmp_path / "re"
    done = rerender(runs["raycast"], "--out", str(out), *sets(), "--set", "renderer.mitsuba.radiance=true")
    assert done.returncode == 0, done.stderr
    assert files(out, "rgb") == files(runs["mitsuba"], "rgb")
    frames = sorted(p.stem for p in (out / "rgb").glob("*.png"))
    assert sorted(p.stem for p in (out / layout.RADIANCE).glob("*.exr")) == frames
    assert not (runs["mitsuba"] / layout.RADIANCE).exists()  # only when asked
    for frame in frames:
        radiance = np.array(mi.Bitmap(str(layout.radiance(out, frame))), np.float32)
        rgb = np.asarray(Image.open(layout.image(out, "rgb", frame)))
        assert radiance.shape == rgb.shape and radiance.max() > 0.05
        encoded = np.empty((rgb.shape[0] * rgb.shape[1], 3), np.uint8)
        encode_srgb8(radiance.reshape(-1, 3).copy(), encoded)
        assert np.array_equal(encoded.reshape(rgb.shape), rgb)


def test_rerender_resumes_frame_by_frame(
    runs: dict[str, Path], rerendered: tuple[Path, str, str, int], tmp_path: Path
) -> None:
    """An interrupted re-render (render.json lists one frame done) goes on with the others and
    leaves the done one as it is."""
    assert rerendered[3] == 0, rerendered[2]
    out = Path(shutil.copytree(rerendered[0], tmp_path / "re"))
    record = json.loads((out / "render.json").read_text())
    first, *rest = record["frames_done"]
    marker = layout.image(runs["raycast"], "rgb", first).read_bytes()  # stands for "kept"
    layout.image(out, "rgb", first).write_bytes(marker)
    for frame in rest:
        layout.image(out, "rgb", frame).unlink()
    (out / "render.json").write_text(json.dumps(dict(record, status="running", frames_done=[first])))
    again = rerender(runs["raycast"], "--out", str(out), *sets(), blocked=())
    assert again.returncode == 0, again.stderr
    assert f"resuming: 1 of {len(record['frames_done'])}" in again.stdout
    assert layout.image(out, "rgb", first).read_bytes() == marker
    assert {f: files(out, "rgb")[f"{f}.png"] for f in rest} == {
        f: files(runs["mitsuba"], "rgb")[f"{f}.png"] for f in rest
    }


@pytest.mark.parametrize(
    ("make", "args", "expected"),
    [
        (
            lambda d: None,
            ["--renderer", "pybullet"],
            ["renderer 'pybullet' cannot re-render", "renderers that can: mitsuba, raycast"],
        ),
        (lambda d: (d / str(layout.SCENE_GLB)).unlink(), [], ["no saved scene", "scene/lab.glb"]),
        (
            lambda d: (d / "run.json").write_text(
                json.dumps(dict(json.loads((d / "run.json").read_text()), status="interrupted"))
            ),
            [],
            ["interrupted, not complete"],
        ),
        (lambda d: next((d / layout.LINK_POSES).glob("*.json")).unlink(), [], ["saved no arm link poses"]),
        (lambda d: None, ["--set", "renderer.mitsuba.spp=0"], ["renderer backend 'mitsuba'", "spp"]),
        (lambda d: None, ["--set", "plant=boxwood"], ["only renderer.* settings"]),
        (lambda d: None, ["--out", "{run}"], ["replaces its RGB", "--overwrite"]),
        (lambda d: (d.parent / "taken").mkdir(), ["--out", "{parent}/taken", "--renderer", "raycast"], []),
        (lambda d: None, ["--gpus", "3"], ["--gpus 3: the Ray cluster has 0 GPU resources"]),
        (lambda d: None, ["--gpus", "0"], ["--gpus must be 1 or more"]),
        (lambda d: None, ["--ray-address", "127.0.0.1:9"], ["--ray-address 127.0.0.1:9"]),
    ],
    ids=[
        "pybullet-cannot",
        "no-scene",
        "incomplete",
        "no-link-poses",
        "bad-option",
        "not-a-renderer-setting",
        "in-place-needs-overwrite",
        "existing-out-empty-is-fine",
        "more-gpus-than-the-cluster",
        "no-gpus",
        "unreachable-cluster",
    ],
)
def test_bad_input_writes_nothing(runs: dict[str, Path], tmp_path: Path, make, args, expected) -> None:  # noqa: ANN001
    import shutil

    src = tmp_path / "run"
    shutil.copytree(runs["raycast"], src)
    make(src)
    before = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file()}
    argv = [a.format(run=src, parent=tmp_path) for a in args]
    done = rerender(src, *argv, *(sets() if "--set" not in args else []), blocked=())
    if not expected:  # an empty --out is not "existing work": the re-render goes ahead (raycast: quick)
        assert done.returncode == 0, done.stderr
        assert sorted(p.name for p in (tmp_path / "taken" / "rgb").glob("*.png")) == sorted(files(src, "rgb"))
        return
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    for fragment in expected:
        assert fragment in done.stderr, done.stderr
    after = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file()}
    assert after == before
    assert not (tmp_path / "run-mitsuba").exists()


# ------------------------------------------------------------------ one run's frames over GPUs


@pytest.fixture(scope="module")
def ray_two_gpus() -> Iterator[None]:
    """A local Ray of two CPUs and two ``fake_gpu``: Ray's custom resources place tasks as its
    GPUs would (a task takes one; none waits for a busy one)."""
    with local_ray(__name__, fake_gpu=2):
        yield


def test_several_runs_go_to_ray_tasks(
    runs: dict[str, Path], ray_two_gpus: None, tmp_path: Path, cli: Callable[..., tuple[int, str, str]]
) -> None:
    """``agrisim render A B``: each run re-rendered by a Ray task into A-mitsuba and B-mitsuba,
    each byte for byte the mitsuba run's RGB. In-process, on the module's local Ray: the
    command uses a Ray already running in its process as it is (starting and stopping its own
    is the more-gpus-than-the-cluster case's, in a fresh interpreter)."""
    sources = [tmp_path / "a", tmp_path / "b"]
    for s in sources:
        shutil.copytree(runs["raycast"], s)
    status, stdout, stderr = cli(["render", str(sources[0]), str(sources[1]), *sets()])
    assert status == 0, stderr
    for s in sources:
        assert files(s.with_name(f"{s.name}-mitsuba"), "rgb") == files(runs["mitsuba"], "rgb")
        assert f"{s}: " in stdout
    status, _, stderr = cli(["render", str(sources[0]), str(sources[1]), "--out", str(tmp_path / "x"), *sets()])
    assert status == 2 and "names the output of one run" in stderr


def logged_part(log: str, marker: str, lost: int) -> Callable[..., dict[str, Any]]:
    """:func:`render_part_task`, each attempt's start and end and every frame it lists done
    logged, and part ``lost``'s worker killed after its first frame on its first attempt."""

    def task(*args: Any) -> dict[str, Any]:
        import os
        import time

        from agrisim.plugins.apps.render import render_part_task

        part = args[5]

        def note(event: str, **more: Any) -> None:
            with open(log, "a") as f:
                f.write(json.dumps({"part": part, "event": event, "t": time.time(), "pid": os.getpid(), **more}) + "\n")

        def on_frame(frame: str) -> None:
            note("frame", frame=frame)
            if part == lost and not Path(marker).exists():
                Path(marker).write_text(str(os.getpid()))
                os._exit(1)  # the worker is lost, as to the OOM killer or a node's end

        note("start")
        record = render_part_task(*args, on_frame=on_frame)
        note("end")
        return record

    return task


def test_one_run_split_over_two_gpus(runs: dict[str, Path], ray_two_gpus: None, tmp_path: Path) -> None:
    """One run, two (fake) GPUs: its frames dealt out to two parts that draw at once, each on
    its own GPU; one part's worker lost after its first frame and retried by Ray, going on from
    its part file. Every frame drawn exactly once, the whole byte for byte the mitsuba run's,
    ``render.json`` complete and the part files gone."""
    from agrisim.plugins.apps.render import PART_JSON, RenderPlan, render_runs

    src = tmp_path / "run"
    shutil.copytree(runs["raycast"], src)
    # variant auto: CUDA where there is a GPU, so the parts go to the (fake) GPUs; Mitsuba's
    # LLVM variant here, as the runs were drawn
    overrides = {"renderer": {"mitsuba": dict(MITSUBA, variant="auto")}}
    plan = RenderPlan(src, "mitsuba", overrides, None, overwrite=False)
    log, marker = tmp_path / "parts.log", tmp_path / "lost"
    seen: list[tuple[int, int]] = []
    records = render_runs(
        [plan], overrides, None, lambda d, n: seen.append((d, n)), gpu_resource="fake_gpu",
        task=logged_part(str(log), str(marker), lost=1),
    )  # fmt: skip
    events = [json.loads(line) for line in log.read_text().splitlines()]
    assert marker.exists(), "the lost worker's attempt never ran"
    assert "error" not in records[0], records
    drawn = [e["frame"] for e in events if e["event"] == "frame"]
    assert sorted(drawn) == sorted(plan.frames)  # each once, the lost attempt's frame not again
    by_part = {p: {e["frame"] for e in events if e["event"] == "frame" and e["part"] == p} for p in (0, 1)}
    assert all(by_part.values()) and not by_part[0] & by_part[1]
    starts = {p: min(e["t"] for e in events if e["event"] == "start" and e["part"] == p) for p in (0, 1)}
    ends = [e["t"] for e in events if e["event"] == "end"]
    assert max(starts.values()) < min(ends), "the two parts did not draw at once"
    attempts = {p: {e["pid"] for e in events if e["event"] == "start" and e["part"] == p} for p in (0, 1)}
    assert len(attempts[0]) == 1 and len(attempts[1]) == 2  # the lost part retried in a new worker
    out = src.with_name("run-mitsuba")
    assert files(out, "rgb") == files(runs["mitsuba"], "rgb")
    doc = json.loads((out / "render.json").read_text())
    assert doc["status"] == "complete" and doc["frames_done"] == plan.frames
    assert not list(out.glob(PART_JSON.format("*")))
    assert seen[-1] == (len(plan.frames), len(plan.frames))


def test_a_split_render_resumes_from_its_parts(runs: dict[str, Path], tmp_path: Path) -> None:
    """A split re-render stopped with one part half done: the next ``agrisim render`` reads the
    part's list, draws only the frames no part listed, merges every list into ``render.json``
    and removes the part files; the whole is the mitsuba run's RGB."""
    from agrisim.plugins.apps.render import PART_JSON, RenderPlan

    src = tmp_path / "run"
    shutil.copytree(runs["raycast"], src)
    overrides = {"renderer": {"mitsuba": MITSUBA}}
    first = RenderPlan(src, "mitsuba", overrides, None, overwrite=False)
    first.prepare()
    assert first.render_frames(first.frames[0::2][:2], part=0) == first.frames[0::2][:2]
    out = first.out
    assert json.loads((out / "render.json").read_text())["frames_done"] == []  # listed in the part only
    again = RenderPlan(src, "mitsuba", overrides, None, overwrite=False)
    assert again.done == first.frames[0::2][:2]
    again.prepare()
    assert again.render_frames(again.frames) == [f for f in again.frames if f not in first.frames[0::2][:2]]
    assert again.finish() == []
    doc = json.loads((out / "render.json").read_text())
    assert doc["status"] == "complete" and doc["frames_done"] == again.frames
    assert not list(out.glob(PART_JSON.format("*")))
    assert files(out, "rgb") == files(runs["mitsuba"], "rgb")
