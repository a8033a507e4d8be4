"""The ``rerun`` sink: a real small episode recorded, then read back with Rerun's own RRD reader."""

from __future__ import annotations

import dataclasses
import importlib
import socket
import subprocess
import sys
import time
import uuid
from collections import defaultdict
from collections.abc import Iterator
from importlib import metadata
from pathlib import Path

import numpy as np
import pinocchio as pin
import pyarrow as pa
import pytest

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

from agrisim.config import build_config  # noqa: E402
from agrisim.episode import Episode  # noqa: E402
from agrisim.interfaces import Capture, Frame, JointTrajectory, Trajectory  # noqa: E402
from agrisim.plugins.render import robot_meshes  # noqa: E402
from agrisim.plugins.rigs.paper.cell import build_cell, hemisphere  # noqa: E402
from agrisim.plugins.sinks import rerun_sink  # noqa: E402
from agrisim.plugins.sinks.rerun_sink import RerunOptions, entities, recording  # noqa: E402
from agrisim.plugins.sinks.rerun_sink.entities import paths  # noqa: E402
from agrisim.records import Run, RunSummary, SetpointResult  # noqa: E402
from agrisim.registry import make_plugin_manager  # noqa: E402
from agrisim.robot.kinematics import ArmKinematics  # noqa: E402
from agrisim.robot.setpoints import routine  # noqa: E402
from agrisim.scene.camera import preset  # noqa: E402

UR10_MESH_LINKS = {
    "base_link",
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
}


@pytest.fixture(autouse=True)
def _isolated_mesh_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    # Converted meshes go to a per-session directory, not the user's cache.
    monkeypatch.setenv("AGRISIM_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "agrisim-cache"))
    rr.set_strict_mode(True)  # a malformed archetype raises instead of logging a warning


# ---------------------------------------------------------------------- reading recordings


class Recording:
    """The chunks of an ``.rrd`` grouped by entity path (leading slash dropped)."""

    def __init__(self, path: Path) -> None:
        reader = RrdReader(path)
        self.recordings = reader.recordings()
        self.blueprints = reader.blueprints()
        self.chunks: dict[str, list] = defaultdict(list)
        for chunk in reader.stream():
            self.chunks[chunk.entity_path.lstrip("/")].append(chunk)

    def temporal(self, entity: str, component: str) -> dict[str, np.ndarray]:
        """Rows of ``entity`` holding ``component``, on every timeline, sorted by row id."""
        rows: dict[str, list] = defaultdict(list)
        for chunk in self.chunks.get(entity, []):
            if chunk.is_static:
                continue
            rb = chunk.to_record_batch()
            if component not in rb.schema.names:
                continue
            rows["row_id"] += [bytes(x) for x in rb.column("rerun.controls.RowId").to_pylist()]
            for name in rb.schema.names:
                if name == "rerun.controls.RowId":
                    continue
                col = rb.column(name)
                if pa.types.is_duration(col.type):
                    rows[name] += list(col.cast(pa.int64()).to_numpy() * 1e-9)
                elif pa.types.is_timestamp(col.type):  # log_time: wall clock, not checked
                    continue
                elif pa.types.is_integer(col.type):
                    rows[name] += list(col.to_numpy())
                else:
                    rows[name] += col.to_pylist()
        order = np.argsort(rows["row_id"]) if rows else []
        return {k: [v[i] for i in order] for k, v in rows.items()}

    def static(self, entity: str, component: str) -> list:
        for chunk in self.chunks.get(entity, []):
            rb = chunk.to_record_batch()
            if chunk.is_static and component in rb.schema.names:
                return rb.column(component).to_pylist()[-1]
        return []


@dataclasses.dataclass
class StoredView:
    """One view of a stored blueprint: what it is, where, and which entities it draws."""

    kind: str  # "3D", "2D", "TimeSeries"
    name: str
    origin: str
    queries: list[str]
    hidden: set[str]  # entity paths an EntityBehavior override makes invisible (with their subtrees)

    def holds(self, entity: str) -> bool:
        """Is ``entity`` in the view's contents (drawn, or listed with its eye off)?"""
        held = False
        for query in self.queries:
            rule = query.strip().replace("$origin", self.origin).lstrip("/")
            # only inclusions are written by the sink; an exclusion would need Rerun's precedence
            assert not rule.startswith("-"), f"{self.name}: exclusion rules are not read here: {query}"
            rule = rule.removeprefix("+").strip()
            if rule.endswith("/**"):
                base = rule.removesuffix("/**")
                held |= entity == base or entity.startswith(base + "/")
            else:
                held |= entity == rule
        return held

    def shows(self, entity: str) -> bool:
        """Is ``entity`` drawn when the recording opens (held, and no ancestor override hides it)?"""
        return self.holds(entity) and not any(entity == h or entity.startswith(h + "/") for h in self.hidden)


class StoredBlueprint:
    """The default blueprint an ``.rrd`` holds: its views in layout order (depth first through the
    containers, as the viewer lays them out) and every blueprint component by entity."""

    def __init__(self, path: Path) -> None:
        reader = RrdReader(path)
        (store,) = reader.blueprints()
        self.rows: dict[str, dict[str, list]] = defaultdict(dict)
        for chunk in reader.stream(store=store):
            rb = chunk.to_record_batch()
            for name in rb.schema.names:
                if ":" in name:  # a component (the others: row ids and the blueprint's own timelines)
                    self.rows[chunk.entity_path.lstrip("/")][name] = rb.column(name).to_pylist()[-1]
        root = self.rows["viewport"]["ViewportBlueprint:root_container"][0]
        self.views = list(self._walk(f"container/{uuid.UUID(bytes=bytes(root))}"))

    def _walk(self, item: str) -> Iterator[StoredView]:
        if item.startswith("container/"):
            for child in self.rows[item]["ContainerBlueprint:contents"]:
                yield from self._walk(child)
            return
        row = self.rows[item]
        prefix = f"{item}/ViewContents/overrides/"
        hidden = {
            path.removeprefix(prefix).removesuffix("/visualizers")
            for path, components in self.rows.items()
            if path.startswith(prefix) and components.get("EntityBehavior:visible") == [False]
        }
        yield StoredView(
            kind=row["ViewBlueprint:class_identifier"][0],
            name=row["ViewBlueprint:display_name"][0],
            origin=row["ViewBlueprint:space_origin"][0].lstrip("/"),
            queries=self.rows[f"{item}/ViewContents"]["ViewContents:query"],
            hidden=hidden,
        )

    def view(self, name: str) -> StoredView:
        (found,) = [v for v in self.views if v.name == name]
        return found

    def components(self, component: str) -> list:
        """Every value of ``component`` anywhere in the blueprint."""
        return [row[component] for row in self.rows.values() if component in row]


def _plugin_manager():
    # Only the backends this test needs: other plugins may be half-written in a working tree.
    pm = make_plugin_manager(autoload=False)
    for name in (
        "agrisim.plugins.physics.kinematic",
        "agrisim.plugins.planners.direct",
        "agrisim.plugins.plants.procedural",  # the plant a robot-only run names is still checked
        "agrisim.plugins.sinks.rerun_sink",
    ):
        pm.register(importlib.import_module(name), name=name)
    return pm


# ---------------------------------------------------------------------- an episode recorded


def test_episode_recording_holds_robots_on_both_timelines(tmp_path: Path) -> None:
    pytest.importorskip("agrisim.plugins.physics.kinematic")
    pytest.importorskip("agrisim.plugins.planners.direct")
    cfg = build_config(
        {
            "physics": {"backend": "kinematic"},
            "planner": {"backend": "direct"},
            "routine": {"setpoints": "2x2"},
            "renderer": {"backend": "none"},
            "output": {"out": str(tmp_path / "run")},
        }
    )
    run, summary = Episode(cfg, _plugin_manager()).run()
    rrd = tmp_path / "run" / "recording.rrd"
    assert rrd.is_file() and rrd.stat().st_size > 100_000
    rec = Recording(rrd)

    assert [r.application_id for r in rec.recordings] == ["agrisim"]
    assert rec.recordings[0].recording_id == entities.recording_id(run)
    assert rec.blueprints, "the default blueprint is saved with the recording"
    assert rec.static("world", "ViewCoordinates:xyz"), "world/ is z-up"
    for name in ("floor", "table", "pot", "r1_stand", "r2_stand"):
        assert rec.chunks.get(f"world/cell/{name}"), name

    moved = {(r.robot, r.index) for r in run.results if r.ee_error_mm is not None}
    assert moved, "the direct planner reached nothing: nothing to check"
    for arm in run.cell.arms:
        kin = run.kinematics[arm.name]
        # Static meshes: one GLB per UR10 link, the camera body as a box.
        for link in UR10_MESH_LINKS:
            blob = rec.static(paths.link_visual(arm.name, link, 0), "Asset3D:blob")
            assert bytes(blob[0][:4]) == b"glTF", (arm.name, link)
        assert rec.static(paths.link_visual(arm.name, "camera_link", 0), "Boxes3D:half_sizes")

        # Link transforms over time, on both timelines, from home (setpoint 0, t = 0) onwards.
        for link in UR10_MESH_LINKS | {"camera_link"}:
            rows = rec.temporal(paths.link(arm.name, link), "Transform3D:translation")
            assert rows, (arm.name, link)
            assert {"setpoint", "sim_time"} <= rows.keys()
            assert len(rows["setpoint"]) == len(rows["sim_time"]) > 1
            assert rows["sim_time"][0] == 0.0 and rows["setpoint"][0] == 0
            home = kin.link_poses(np.array(arm.home))[link][:3, 3]
            np.testing.assert_allclose(rows["Transform3D:translation"][0][0], home, atol=1e-5)
            assert max(rows["sim_time"]) <= summary.sim_time + 1e-9
            assert set(rows["setpoint"]) == {i for r, i in moved if r == arm.name} | {0}

        # The last row logged at each setpoint puts the camera where it was captured.
        cam = rec.temporal(paths.camera(arm.name), "Transform3D:translation")
        for result in run.results:
            if result.robot != arm.name or not result.reached:
                continue
            last = max(i for i, s in enumerate(cam["setpoint"]) if s == result.index)
            target = run.setpoints[arm.name][result.index].world_T_camera[:3, 3]
            np.testing.assert_allclose(cam["Transform3D:translation"][last][0], target, atol=1e-5)
        pinholes = rec.temporal(paths.camera(arm.name), "Pinhole:image_from_camera")
        assert len(pinholes["setpoint"]) == sum(r.reached for r in run.results if r.robot == arm.name)

        errors = rec.temporal(paths.metric(arm.name, "ee_error_mm"), "Scalars:scalars")
        assert len(errors.get("setpoint", [])) == sum(1 for r, _ in moved if r == arm.name)
        assert rec.temporal(paths.planned(arm.name), "LineStrips3D:strips")
        assert rec.temporal(paths.executed(arm.name), "LineStrips3D:strips")
        assert len(rec.static(paths.setpoints(arm.name), "Points3D:positions")) == len(run.setpoints[arm.name])
    summary_text = rec.static(paths.RUN_SUMMARY, "TextDocument:text")
    assert summary_text and "complete" in summary_text[0]


# ---------------------------------------------------------------------- hooks driven by hand


def _hand_built_run(tmp_path: Path, **output: object) -> Run:
    cfg = build_config(
        {"routine": {"setpoints": "1x2"}, "cell": {"arms": 1}, "output": {"out": str(tmp_path / "run"), **output}}
    )
    cell = build_cell(cfg.cell)
    (tmp_path / "run").mkdir()
    known: dict[str, object] = dict(
        config=cfg,
        cell=cell,
        out_dir=tmp_path / "run",
        kinematics={a.name: ArmKinematics(a) for a in cell.arms},
        setpoints=routine(cell, cfg.routine, hemisphere),
        camera=preset("rpi3-wide-1080p", "64x36"),
        backends={"physics": "none", "planner": "none"},
        started_at="2024-01-01T00:00:00+00:00",
    )
    # Fields the sink does not read may be added to Run over time: give them empty values.
    for f in dataclasses.fields(Run):
        if f.name not in known and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            known[f.name] = {} if str(f.type).startswith("dict") else None
    return Run(**known)


def _make(run: Run):  # noqa: ANN202 - the sink or None
    """The sink as the episode builds it: options from the run's [sink.rerun] (the aliases
    --rrd, --no-rrd, --spawn resolved there)."""
    return rerun_sink.make_sink(run, RerunOptions.model_validate(run.config.sink.get("rerun", {})))


def test_hooks_record_motion_images_and_clouds(tmp_path: Path) -> None:
    custom = tmp_path / "elsewhere" / "custom.rrd"
    run = _hand_built_run(tmp_path, rrd=str(custom))
    sink = _make(run)
    assert sink is not None
    arm = run.cell.arms[0]
    home = np.array(arm.home)
    goal = home + np.array([0.3, -0.2, 0.1, 0.0, 0.2, 0.5])
    t = np.linspace(0.0, 2.0, 481)  # 240 Hz for 2 s
    q = home + (goal - home) * (t / t[-1])[:, None]
    trajectory = Trajectory("r1", 0, np.stack([home, goal]), JointTrajectory(t, q), JointTrajectory(t, q))
    kin = run.kinematics["r1"]
    cam = run.camera
    images = Frame(
        rgb=np.full((cam.height, cam.width, 3), 120, np.uint8),
        labels=np.zeros((cam.height, cam.width), np.uint8),
        depth=np.full((cam.height, cam.width), 0.5, np.float32),
    )
    capture = Capture("r1", "r1_000", 0, 2.0, kin.fk(goal), cam, images)

    sink.agrisim_run_started(run=run)
    sink.agrisim_trajectory(run=run, robot="r1", trajectory=trajectory)
    sink.agrisim_setpoint(
        run=run, robot="r1", result=SetpointResult("r1", 0, "r1_000", True, ee_error_mm=0.01, sim_time=2.0)
    )
    sink.agrisim_capture(run=run, capture=capture)
    sink.log_label_table({0: ("background", (0, 0, 0)), 1: ("plant", (0, 200, 0))})
    sink.agrisim_cloud(run=run, label="plant", cloud=np.random.default_rng(0).random((50, 3)), merged=True)
    sink.agrisim_setpoint(
        run=run, robot="r1", result=SetpointResult("r1", 1, "r1_001", False, reason="ik: nope", sim_time=2.0)
    )
    sink.agrisim_run_finished(run=run, summary=RunSummary("complete", 2, 1, 1, 0, 2.0, {"ik": 0.1}))
    assert sink.rec is None, "the stream is closed at the end of the run"
    assert not (run.out_dir / "recording.rrd").exists(), "--rrd moves the recording"

    rec = Recording(custom)
    rows = rec.temporal(paths.link("r1", "wrist_3_link"), "Transform3D:quaternion")
    # Home, then the move decimated to 30 Hz: 2 s -> 61 samples including both ends.
    assert len(rows["sim_time"]) == 1 + 61
    np.testing.assert_allclose(np.diff(rows["sim_time"][1:]), 1 / 30, atol=1 / 240 + 1e-9)
    final = kin.link_poses(goal)["wrist_3_link"]
    np.testing.assert_allclose(
        rows["Transform3D:quaternion"][-1][0], entities.quaternions_xyzw(final[:3, :3])[0], atol=1e-6
    )
    for kind, component in (
        ("rgb", "EncodedImage:blob"),
        ("labels", "SegmentationImage:buffer"),
        ("depth", "DepthImage:buffer"),
    ):
        entity = paths.camera_image("r1", kind)
        got = rec.temporal(entity, component) or rec.temporal(entity, "Image:buffer")
        assert got and got["setpoint"] == [0] and got["sim_time"] == [2.0], kind
    assert rec.static(paths.camera_image("r1", "labels"), "AnnotationContext:context")
    assert rec.temporal(paths.cloud("plant", merged=True), "Points3D:positions")
    colors = rec.temporal(paths.setpoints("r1"), "Points3D:colors")
    assert len(colors["setpoint"]) == 3  # pending at start, then one update per setpoint
    assert rec.temporal(paths.log("r1"), "TextLog:text")["TextLog:text"][-1][0].startswith("r1_001: not reached")


# ---------------------------------------------------------------------- the layout a viewer opens


def test_blueprint_shows_photographs_and_merged_clouds(saved_runs) -> None:  # noqa: ANN001
    """The blueprint stored in a real run's recording: each camera panel draws the photograph,
    with labels and leaf instances held as overlays switched off; depth has a panel of its own;
    the 3D view draws the cell and the merged clouds, and holds each view's depth and cloud
    switched off (they stay in the recording, one click from showing)."""
    run_dir = saved_runs.get(output={"no_rrd": False})
    rrd = run_dir / "recording.rrd"
    recorded = Recording(rrd)
    entities_ = set(recorded.chunks)
    blueprint = StoredBlueprint(rrd)
    arms = ("r1", "r2")
    view_clouds = {e for e in entities_ if e.startswith(paths.VIEW_CLOUDS + "/")}
    merged_clouds = {e for e in entities_ if e.startswith(paths.MERGED_CLOUDS + "/")}
    assert view_clouds and merged_clouds, "the run reconstructed nothing: nothing to check"
    images = {kind: {paths.camera_image(a, kind) for a in arms} for kind in paths.IMAGE_KINDS}
    assert set().union(*images.values()) <= entities_

    names = [v.name for v in blueprint.views]
    for arm in arms:
        camera, depth = blueprint.view(f"{arm} camera"), blueprint.view(f"{arm} depth")
        assert names.index(camera.name) < names.index(depth.name)  # the photograph first
        held = {e for e in entities_ if camera.holds(e)}
        assert {e for e in held if camera.shows(e)} == {paths.camera_image(arm, "rgb")}
        assert held == {paths.camera_image(arm, kind) for kind in ("rgb", "labels", "instances")}
        assert camera.kind == depth.kind == "2D" and camera.origin == depth.origin == paths.camera(arm)
        assert {e for e in entities_ if depth.shows(e)} == {paths.camera_image(arm, "depth")}

    cell = blueprint.view("cell")
    assert cell.kind == "3D" and cell.origin == paths.WORLD
    world = {e for e in entities_ if e == paths.WORLD or e.startswith(paths.WORLD + "/")}
    assert all(cell.holds(e) for e in world)
    hidden = {e for e in world if not cell.shows(e)}
    assert hidden == view_clouds | images["depth"] | images["labels"] | images["instances"]
    shown = world - hidden
    assert merged_clouds | images["rgb"] <= shown
    assert any(e.startswith("world/scene/") for e in shown) and paths.link_visual("r1", "base_link", 0) in shown

    # Naming a timeline makes the viewer look it up before any row on it has arrived (a gRPC
    # server replays blueprints ahead of all data): "Timeline sim_time not found". Unnamed, the
    # viewer takes the timeline with the most rows, its own log_time and log_tick last, ties to
    # the later name (Rerun's time_control.rs, default_timeline): that must be sim_time.
    assert not blueprint.components("TimePanelBlueprint:timeline")
    rows: dict[str, int] = defaultdict(int)
    for chunks in recorded.chunks.values():
        for chunk in chunks:
            if not chunk.is_static:
                rb = chunk.to_record_batch()
                for timeline in ("setpoint", "sim_time", "log_time", "log_tick"):
                    rows[timeline] += rb.num_rows if timeline in rb.schema.names else 0
    assert max(rows, key=lambda t: (rows[t], t not in ("log_time", "log_tick"), t)) == "sim_time", dict(rows)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_spawn_tees_to_the_viewer_and_the_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # A Rerun gRPC server in a child process stands in for the spawned viewer (no display here).
    port = _free_port()
    server = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"import rerun as rr, time; r = rr.RecordingStream('viewer'); r.serve_grpc(grpc_port={port}); time.sleep(60)",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 15
        while not recording._listening(port):
            assert time.monotonic() < deadline and server.poll() is None, "the stand-in viewer did not start"
            time.sleep(0.1)
        spawned: list[int] = []
        monkeypatch.setattr(rr.RecordingStream, "spawn", lambda self, port, connect: spawned.append(port))
        monkeypatch.setattr(recording, "SPAWN_PORT", port)
        run = _hand_built_run(tmp_path, spawn=True)
        sink = _make(run)
        assert sink is not None
        t0 = time.monotonic()
        sink.agrisim_run_started(run=run)
        assert spawned == [port] and sink.rec is not None
        sink.agrisim_run_finished(run=run, summary=RunSummary("complete", 0, 0, 0, 0, 0.0, {}))
        assert time.monotonic() - t0 < recording.FLUSH_TIMEOUT
    finally:
        server.kill()
        server.wait()
    rec = Recording(run.out_dir / "recording.rrd")
    assert rec.static(paths.RUN_SUMMARY, "TextDocument:text")


def test_spawn_without_a_viewer_records_to_file_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rr.RecordingStream, "spawn", lambda self, port, connect: None)
    monkeypatch.setattr(recording, "SPAWN_PORT", _free_port())  # nothing listens there
    run = _hand_built_run(tmp_path, spawn=True, no_rrd=True)
    sink = _make(run)
    assert sink is not None  # --spawn asks for a viewer even under --no-rrd
    sink.agrisim_run_started(run=run)
    assert sink.rec is None, "no sink at all: nothing is buffered in memory"
    sink.agrisim_run_finished(run=run, summary=RunSummary("complete", 0, 0, 0, 0, 0.0, {}))
    assert not (run.out_dir / "recording.rrd").exists()


def test_no_rrd_without_spawn_stays_out(tmp_path: Path) -> None:
    run = _hand_built_run(tmp_path, no_rrd=True)
    assert _make(run) is None


def test_registered_through_the_entry_point() -> None:
    eps = {ep.name: ep.value for ep in metadata.entry_points(group="agrisim")}
    assert eps.get("sink-rerun") == "agrisim.plugins.sinks.rerun_sink"
    (spec,) = rerun_sink.agrisim_sinks()
    assert spec.name == "rerun" and spec.factory is rerun_sink.make_sink and spec.description


# ---------------------------------------------------------------------- helpers


def test_quaternions_match_pinocchio() -> None:
    Rs = [pin.SE3.Random().rotation for _ in range(500)]
    Rs += [np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0]), np.eye(3)]
    q = entities.quaternions_xyzw(np.array(Rs))
    ref = np.array([pin.Quaternion(R).coeffs() for R in Rs])  # x, y, z, w
    err = np.minimum(np.abs(q - ref).max(axis=1), np.abs(q + ref).max(axis=1))
    assert err.max() < 1e-12


def test_decimate_keeps_both_ends() -> None:
    t = np.arange(0, 1.0 + 1e-9, 1 / 240)
    idx = entities.decimate(t, 30.0)
    assert idx[0] == 0 and idx[-1] == len(t) - 1 and len(idx) == 31
    assert list(entities.decimate(np.array([3.0]), 30.0)) == [0]
    assert len(entities.decimate(np.array([]), 30.0)) == 0


def test_link_visuals_and_mesh_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    cell = build_cell(build_config({}).cell)
    visuals = robot_meshes.link_visuals(cell.arms[0].urdf)
    assert set(visuals) == UR10_MESH_LINKS | {"camera_link"}
    assert visuals["camera_link"][0].kind == "box"
    mesh = visuals["wrist_3_link"][0]
    assert mesh.kind == "mesh" and mesh.filename.endswith(".dae")

    monkeypatch.setenv("AGRISIM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(robot_meshes, "_memory", {})
    data = robot_meshes.glb_bytes(mesh.filename)
    assert data[:4] == b"glTF"
    (cached,) = (tmp_path / "cache" / "meshes").glob("wrist3-*.glb")
    # A second process (empty memory cache) reads the disk copy instead of converting again.
    monkeypatch.setattr(robot_meshes, "_memory", {})
    monkeypatch.setattr(robot_meshes, "_convert", lambda path: pytest.fail("converted twice"))
    assert robot_meshes.glb_bytes(mesh.filename) == data == cached.read_bytes()
