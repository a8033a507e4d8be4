"""``agrisim export rosbag``: the bag read back message by message with ``mcap`` +
``mcap-ros2-support`` (not the library that wrote it), against the run's own files: images equal
to the PNGs, depth to the PNG's millimetres (REP 118 metres, +Inf for no hit), ``camera_info``'s K
to ``cameras.json``, the TF chain from ``world`` to each camera's optical frame equal to the
frame's ``world_T_camera`` at its stamp, joint states equal to the executed samples in
``trajectories/``, the cloud to ``clouds/``; robot-only runs, ``metadata.yaml``, the refusals."""

from __future__ import annotations

import json
import shutil
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import small_run
from mcap_ros2.reader import read_ros2_messages
from PIL import Image
from ruamel.yaml import YAML


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Hydrangea with organ labels and leaf instances, kinematic arms."""
    return small_run(tmp_path_factory.mktemp("bag") / "run", plant="hydrangea", render={"labels": "organs"})


def read_bag(run_dir: Path) -> dict[str, list[Any]]:
    """Every message of the bag by topic, in log-time order, each with its log time checked
    equal to its header stamp."""
    topics: dict[str, list[Any]] = defaultdict(list)
    for m in read_ros2_messages(str(run_dir / "rosbag" / "rosbag.mcap")):
        msg = m.ros_msg
        if hasattr(msg, "header"):
            assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == m.log_time_ns
        topics[m.channel.topic].append((m.log_time_ns, msg))
    return topics


def stamp(t: float) -> int:
    return round(t * 1e9)


def matrix(tf: Any) -> np.ndarray:
    """A geometry_msgs Transform as 4x4 (the unit quaternion's rotation matrix, written out)."""
    x, y, z, w = tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w
    T = np.eye(4)
    T[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    T[:3, 3] = tf.translation.x, tf.translation.y, tf.translation.z
    return T


def chain(edges: dict[str, tuple[str, np.ndarray]], frame: str) -> np.ndarray:
    """``world_T_frame`` by walking child -> parent edges up to ``world``."""
    T = np.eye(4)
    while frame != "world":
        parent, parent_T_child = edges[frame]
        T = parent_T_child @ T
        frame = parent
    return T


def png(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path))


def pixels(msg: Any, dtype: str, channels: int = 1) -> np.ndarray:
    shape = (msg.height, msg.width, channels) if channels > 1 else (msg.height, msg.width)
    assert msg.step == msg.width * np.dtype(dtype).itemsize * channels and not msg.is_bigendian
    return np.frombuffer(bytes(msg.data), dtype).reshape(shape)


def static_edges(topics: dict[str, list[Any]]) -> dict[str, tuple[str, np.ndarray]]:
    ((_, static),) = topics["/tf_static"]
    return {t.child_frame_id: (t.header.frame_id, matrix(t.transform)) for t in static.transforms}


def test_bag_reads_back_as_the_run(run_dir: Path, cli) -> None:  # noqa: ANN001
    code, out, _ = cli(["export", "rosbag", str(run_dir)])
    assert code == 0 and "rosbag" in out
    topics = read_bag(run_dir)
    run = json.loads((run_dir / "run.json").read_text())
    cameras = json.loads((run_dir / "cameras.json").read_text())
    K = np.asarray(cameras["intrinsics"]["K"])
    frames = cameras["frames"]
    assert sorted(frames) == sorted(run["frames_complete"]) and len(frames) == 6

    # metadata.yaml, as ros2 bag info reads it: the topics and their counts are the MCAP's
    meta = YAML(typ="safe").load((run_dir / "rosbag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap" and meta["relative_file_paths"] == ["rosbag.mcap"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    assert counts == {topic: len(msgs) for topic, msgs in topics.items()}
    assert meta["message_count"] == sum(counts.values())
    static_qos = next(t for t in meta["topics_with_message_count"] if t["topic_metadata"]["name"] == "/tf_static")
    assert static_qos["topic_metadata"]["offered_qos_profiles"][0]["durability"] == "transient_local"
    assert json.loads(meta["custom_data"]["agrisim.labels"]) == run["labels"]

    static = static_edges(topics)
    tf_at = {t: msg for t, msg in topics["/tf"]}
    for frame, entry in frames.items():
        arm, t = entry["robot"], stamp(entry["sim_time"])
        optical = f"{arm}/camera_optical_frame"
        # the images: the run's PNGs, in the camera's optical frame, at the capture's stamp
        by_topic = {
            name: dict(topics[f"/{arm}/camera/{name}"])
            for name in ("image_raw", "depth", "labels", "instances", "camera_info")
        }
        msgs = {name: by_topic[name][t] for name in by_topic}
        assert all(m.header.frame_id == optical for m in msgs.values())
        assert msgs["image_raw"].encoding == "rgb8"
        assert np.array_equal(pixels(msgs["image_raw"], "u1", 3), png(run_dir / "rgb" / f"{frame}.png"))
        assert msgs["labels"].encoding == "mono8"
        assert np.array_equal(pixels(msgs["labels"], "u1"), png(run_dir / "labels" / f"{frame}.png"))
        assert msgs["instances"].encoding == "mono16"
        assert np.array_equal(pixels(msgs["instances"], "<u2"), png(run_dir / "instances" / f"{frame}.png"))
        assert msgs["depth"].encoding == "32FC1"
        depth, mm = pixels(msgs["depth"], "<f4"), png(run_dir / "depth" / f"{frame}.png")
        assert np.array_equal(np.isinf(depth), mm == 0)
        assert np.array_equal(depth[mm > 0], mm[mm > 0].astype(np.float32) / np.float32(1000))
        info = msgs["camera_info"]
        assert np.array_equal(np.reshape(info.k, (3, 3)), K)
        assert np.array_equal(np.reshape(info.p, (3, 4))[:, :3], K) and not np.any(info.d)
        assert (info.width, info.height) == (cameras["intrinsics"]["width"], cameras["intrinsics"]["height"])
        # TF: world -> ... -> the optical frame at this stamp is the pose the frame was rendered from
        edges = dict(static)
        edges.update({tr.child_frame_id: (tr.header.frame_id, matrix(tr.transform)) for tr in tf_at[t].transforms})
        assert np.abs(chain(edges, optical) - np.asarray(entry["world_T_camera"])).max() < 1e-6

    # joint states: every executed sample of every move, exactly
    states = {arm: dict(topics[f"/{arm}/joint_states"]) for arm in ("r1", "r2")}
    plans = {arm: topics[f"/{arm}/planned_trajectory"] for arm in ("r1", "r2")}
    moves = sorted((run_dir / "trajectories").glob("*.json"))
    assert len(moves) == 6 and sum(len(p) for p in plans.values()) == 6
    docs = sorted((json.loads(path.read_text()) for path in moves), key=lambda d: d["executed"]["t"][0])
    executed: dict[str, dict[int, tuple[list[float], list[float]]]] = {"r1": {}, "r2": {}}
    for doc in docs:  # a move starts where (and when) the last one ended: the later sample is kept
        for t, q, qd in zip(doc["executed"]["t"], doc["executed"]["q"], doc["executed"]["qd"], strict=True):
            executed[doc["robot"]][stamp(t)] = (q, qd)
    for arm, samples in executed.items():
        for t, (q, qd) in samples.items():
            assert list(states[arm][t].name) == docs[0]["joints"]
            assert np.array_equal(states[arm][t].position, q) and np.array_equal(states[arm][t].velocity, qd)
    for doc in docs:
        arm = doc["robot"]
        start, plan = next((s, p) for s, p in plans[arm] if s == stamp(doc["planned"]["t"][0]))
        assert list(plan.joint_names) == doc["joints"] and len(plan.points) == len(doc["planned"]["t"])
        for point, t, q in zip(plan.points, doc["planned"]["t"], doc["planned"]["q"], strict=True):
            assert np.array_equal(point.positions, q)
            assert abs(point.time_from_start.sec * 10**9 + point.time_from_start.nanosec + start - t * 1e9) <= 1
    # TF and joint states tick together: one TF message per stamp, with every moving joint
    assert sorted(tf_at) == sorted(states["r1"]) == sorted(states["r2"])
    assert all(len(msg.transforms) == 12 for msg in tf_at.values())

    # the cloud: every label's merged cloud, its points, colours and label ids
    ((_, cloud),) = topics["/reconstruction/cloud"]
    assert cloud.header.frame_id == "world"
    fields = {f.name: (f.offset, f.datatype) for f in cloud.fields}
    assert fields == {"x": (0, 7), "y": (4, 7), "z": (8, 7), "rgb": (12, 7), "label": (16, 2)}
    rows = np.frombuffer(
        bytes(cloud.data),
        np.dtype(
            {
                "names": ["xyz", "rgb", "label"],
                "formats": [("<f4", 3), "<u4", "u1"],
                "offsets": [0, 12, 16],
                "itemsize": cloud.point_step,
            }
        ),
    )
    import trimesh

    for label in run["labels"][1:]:
        ply = trimesh.load(run_dir / "clouds" / f"{label['name']}.ply", process=False)
        mine = rows[rows["label"] == label["id"]]
        assert len(mine) == len(ply.vertices) > 0
        assert np.array_equal(mine["xyz"], np.asarray(ply.vertices, np.float32))
        rgb = np.stack([(mine["rgb"] >> 16) & 255, (mine["rgb"] >> 8) & 255, mine["rgb"] & 255], axis=1)
        assert np.array_equal(rgb, np.asarray(ply.colors)[:, :3])


def test_pybullet_arms_hold_their_pose_until_the_capture(tmp_path: Path, cli) -> None:  # noqa: ANN001
    """Under pybullet the arms settle after their plans and report no velocities; an arm done
    earlier holds its last sample, so TF at every capture is the rendered pose."""
    run_dir = small_run(tmp_path / "run", physics={"backend": "pybullet"}, recon={"backend": "none"})
    assert cli(["export", "rosbag", str(run_dir)])[0] == 0
    topics = read_bag(run_dir)
    static = static_edges(topics)
    tf_at = dict(topics["/tf"])
    frames = json.loads((run_dir / "cameras.json").read_text())["frames"]
    for entry in frames.values():
        edges = dict(static)
        edges.update(
            {
                tr.child_frame_id: (tr.header.frame_id, matrix(tr.transform))
                for tr in tf_at[stamp(entry["sim_time"])].transforms
            }
        )
        assert (
            np.abs(chain(edges, f"{entry['robot']}/camera_optical_frame") - np.asarray(entry["world_T_camera"])).max()
            < 1e-6
        )
    assert all(len(msg.velocity) == 0 for _, msg in topics["/r1/joint_states"][1:])
    assert "/reconstruction/cloud" not in topics  # no reconstruction, no cloud


def test_robot_only_run_exports_robot_topics(tmp_path: Path, cli) -> None:  # noqa: ANN001
    run_dir = small_run(tmp_path / "run", renderer={"backend": "none"})
    assert cli(["export", "rosbag", str(run_dir)])[0] == 0
    topics = read_bag(run_dir)
    assert set(topics) == {
        "/tf_static",
        "/tf",
        "/r1/joint_states",
        "/r2/joint_states",
        "/r1/planned_trajectory",
        "/r2/planned_trajectory",
    }
    # COCO needs images: refused with one line, nothing written
    code, _, err = cli(["export", "coco", str(run_dir)])
    assert code == 2 and "--renderer none" in err and len(err.strip().splitlines()) == 1
    assert not (run_dir / "coco").exists()


def test_refusals_write_nothing(run_dir: Path, cli, tmp_path: Path) -> None:  # noqa: ANN001
    bag = run_dir / "rosbag"
    if not bag.exists():
        assert cli(["export", "rosbag", str(run_dir)])[0] == 0
    before = (bag / "rosbag.mcap").read_bytes()
    code, _, err = cli(["export", "rosbag", str(run_dir)])
    assert code == 2 and "--overwrite" in err and len(err.strip().splitlines()) == 1
    assert (bag / "rosbag.mcap").read_bytes() == before
    assert cli(["export", "rosbag", str(run_dir), "--overwrite"])[0] == 0
    assert sorted(p.name for p in run_dir.iterdir() if p.name.startswith(".")) == []  # no staging left

    def copy(name: str, status: str = "complete", trajectories: bool = True) -> Path:
        out = tmp_path / name
        shutil.copytree(
            run_dir, out, ignore=shutil.ignore_patterns("rosbag", *(() if trajectories else ("trajectories",)))
        )
        doc = json.loads((out / "run.json").read_text())
        (out / "run.json").write_text(json.dumps(dict(doc, status=status)))
        return out

    malformed = copy("malformed")
    move = next((malformed / "trajectories").glob("*.json"))
    move.write_text(json.dumps({k: v for k, v in json.loads(move.read_text()).items() if k != "executed"}))
    cases = (
        (copy("running", status="running"), "not complete"),
        (copy("old", trajectories=False), "trajectories"),
        (malformed, "not an agrisim trajectory"),
    )
    for broken, words in cases:
        code, _, err = cli(["export", "rosbag", str(broken)])
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1, err
        assert not (broken / "rosbag").exists() and not [p for p in broken.iterdir() if p.name.startswith(".")]


def test_depth_is_rep118_metres_with_inf_for_no_hit(tmp_path: Path) -> None:
    """A room hides the sky, so the runs above hit something everywhere: the no-hit rule on
    hand-made depth, from a PNG (millimetres) and from an EXR (exact metres)."""
    from agrisim.files.exr import write_exr
    from agrisim.plugins.exporters.rosbag import frame_depth

    rng = np.random.default_rng(0)
    metres = rng.uniform(0.2, 3.0, (6, 8)).astype(np.float32)
    metres[0, :3] = 0  # nothing hit
    (tmp_path / "depth").mkdir()
    Image.fromarray(np.round(metres * 1000).astype(np.uint16)).save(tmp_path / "depth" / "a.png")
    write_exr(tmp_path / "depth" / "b.exr", metres)
    from_png, from_exr = frame_depth(tmp_path, "a"), frame_depth(tmp_path, "b")
    for depth in (from_png, from_exr):
        assert depth.dtype == np.float32 and np.isposinf(depth[0, :3]).all() and np.isfinite(depth[metres > 0]).all()
    assert np.array_equal(from_exr[metres > 0], metres[metres > 0])
    assert np.abs(from_png[metres > 0] - metres[metres > 0]).max() <= 0.0005 + 1e-7
