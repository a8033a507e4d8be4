"""A bench's plants survive every export and its reader: ``run.json`` names them, COCO's
annotations (read by pycocotools) each carry the plant they lie on, nerfstudio's
``transforms.json`` points each frame at its plant ids, the Rerun recording (read by Rerun's own
reader) holds the plant image with an annotation context naming each plant, the ROS 2 bag (read
by rosbags) publishes it, and ``agrisim render`` keeps ``plants/`` byte for byte from a scene
that still knows each plant's faces. Truth: the run's own ``plants/<frame>.png``, which
``tests/e2e/test_bench.py`` checks against an independent ray caster. A run of one plant gains
none of it.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from agrisim.app.cli import main
from agrisim.files import layout

SMALL = ["--setpoints", "1x2", "--resolution", "64x48", "--physics", "kinematic", "--shadow-samples", "0"]
FAST = [*SMALL, "--recon", "none"]
#: what run.json records of ``--rig gantry --bench 1x2``: the default plant, seeds from --seed 0
BENCH = [
    {"id": 1, "name": "plant_01", "plant": "indian_cress", "seed": 0, "x": -0.25, "y": 0.0},
    {"id": 2, "name": "plant_02", "plant": "indian_cress", "seed": 1, "x": 0.25, "y": 0.0},
]


def png(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        return np.array(im)


def agrisim(*args: str) -> None:
    assert main(list(args)) == 0, args


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two plants under the gantry, two views of each, with the recording."""
    out = tmp_path_factory.mktemp("bench") / "run"
    agrisim("run", "--rig", "gantry", "--bench", "1x2", *FAST, "--out", str(out))
    return out


def plant_images(run: Path) -> dict[str, np.ndarray]:
    frames = json.loads((run / layout.RUN_JSON).read_text())["frames_complete"]
    return {f: png(layout.image(run, layout.PLANTS, f)) for f in frames}


def test_run_json_names_each_plant(bench: Path) -> None:
    """run.json's ``bench``: each plant's id, name, what grew it, seed and place, and its faces of
    the joined plant mesh (one range after another); each id is seen in plants/."""
    rows = json.loads((bench / layout.RUN_JSON).read_text())["bench"]
    assert [{k: v for k, v in row.items() if k != "faces"} for row in rows] == BENCH
    starts, ends = [row["faces"][0] for row in rows], [row["faces"][1] for row in rows]
    assert starts[0] == 0 and starts[1:] == ends[:-1] and all(a < b for a, b in zip(starts, ends, strict=True))
    seen = set().union(*(np.unique(ids).tolist() for ids in plant_images(bench).values()))
    assert seen == {0, 1, 2}


def test_each_coco_annotation_carries_its_plant(bench: Path, tmp_path: Path) -> None:
    """pycocotools loads the export; every annotation's pixels lie on the one plant it names,
    and together they cover every plant pixel."""
    from pycocotools.coco import COCO

    out = tmp_path / "annotations.json"
    agrisim("export", "coco", str(bench), str(out))
    coco = COCO(str(out))
    assert coco.dataset["plants"] == BENCH
    plants = plant_images(bench)
    assert sorted(img["file_name"] for img in coco.dataset["images"]) == [f"rgb/{f}.png" for f in sorted(plants)]
    for image in coco.dataset["images"]:
        ids = plants[Path(image["file_name"]).stem]
        covered = np.zeros(ids.shape, bool)
        for ann in coco.loadAnns(coco.getAnnIds(imgIds=[image["id"]])):
            mask = coco.annToMask(ann).astype(bool)
            assert ann["plant"] in (1, 2) and np.all(ids[mask] == ann["plant"]), ann["id"]
            assert not np.any(covered & mask)
            covered |= mask
        assert np.array_equal(covered, ids > 0), image["file_name"]


def test_nerfstudio_frames_point_at_their_plants(bench: Path) -> None:
    """transforms.json (the run wrote it): each frame's ``plant_mask_path`` is its plants/ image
    and ``plants`` names the ids; ``masks/`` stay nerfstudio's one-channel masks of every plant."""
    doc = json.loads((bench / layout.TRANSFORMS_JSON).read_text())
    assert doc["plants"] == BENCH
    plants = plant_images(bench)
    assert len(doc["frames"]) == len(plants) == 4
    for frame in doc["frames"]:
        name = Path(frame["file_path"]).stem
        ids = png(bench / frame["plant_mask_path"])
        assert ids.dtype == np.uint16 and np.array_equal(ids, plants[name])
        with Image.open(bench / frame["mask_path"]) as mask:
            assert mask.mode == "L"  # one channel, as nerfstudio requires
            assert np.array_equal(np.array(mask) > 0, ids > 0)


def test_the_recording_names_each_plants_pixels(bench: Path) -> None:
    """Rerun's reader: the camera's ``plants`` segmentation image at each capture is plants/, and
    its annotation context names ids 1 and 2 ``plant_01`` and ``plant_02``."""
    from rerun.chunk import RrdReader

    from agrisim.plugins.sinks.rerun_sink.entities import paths

    entity = paths.camera_image("g1", paths.PLANTS)
    context: list[Any] = []
    images: dict[int, np.ndarray] = {}
    for chunk in RrdReader(bench / layout.RECORDING).stream():
        if chunk.entity_path.lstrip("/") != entity:
            continue
        rb = chunk.to_record_batch()
        if chunk.is_static:
            (context,) = rb.column("AnnotationContext:context").to_pylist()[-1]  # one row, one context
            continue
        for setpoint, buffer, form in zip(
            rb.column("setpoint").to_pylist(),
            rb.column("SegmentationImage:buffer").to_pylist(),
            rb.column("SegmentationImage:format").to_pylist(),
            strict=True,
        ):
            (f,) = form
            images[setpoint] = np.frombuffer(bytes(buffer[0]), "<u2").reshape(f["height"], f["width"])
    assert [(c["class_id"], c["class_description"]["info"]["label"]) for c in context] == [
        (1, "plant_01"),
        (2, "plant_02"),
    ]
    frames = json.loads((bench / layout.CAMERAS_JSON).read_text())["frames"]
    plants = plant_images(bench)
    assert sorted(images) == sorted(entry["setpoint"] for entry in frames.values())
    for name, entry in frames.items():
        assert np.array_equal(images[entry["setpoint"]], plants[name]), name
    # the blueprint: the camera's panel holds the plants as an overlay, switched off
    reader = RrdReader(bench / layout.RECORDING)
    (store,) = reader.blueprints()
    queries, hidden = [], set()
    for chunk in reader.stream(store=store):
        rb = chunk.to_record_batch()
        if "ViewContents:query" in rb.schema.names:
            queries += rb.column("ViewContents:query").to_pylist()[-1]
        if "EntityBehavior:visible" in rb.schema.names and rb.column("EntityBehavior:visible").to_pylist()[-1] == [
            False
        ]:
            hidden.add(chunk.entity_path.removesuffix("/visualizers"))
    assert f"$origin/{paths.PLANTS}" in queries
    assert any(h.endswith(f"/ViewContents/overrides/{entity}") for h in hidden), hidden


def test_the_ros_bag_publishes_each_frames_plants(bench: Path, tmp_path: Path) -> None:
    """rosbags reads ``/g1/camera/plants`` (mono16) back as plants/, and the bench in the bag's
    custom data."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    out = tmp_path / "bag"
    agrisim("export", "rosbag", str(bench), str(out))
    store = get_typestore(Stores.ROS2_JAZZY)
    frames = json.loads((bench / layout.CAMERAS_JSON).read_text())["frames"]
    by_stamp = {round(entry["sim_time"] * 1e9): name for name, entry in frames.items()}
    plants, got = plant_images(bench), {}
    with Reader(out) as reader:
        topic = [c for c in reader.connections if c.topic == "/g1/camera/plants"]
        for connection, stamp, raw in reader.messages(connections=topic):
            msg = store.deserialize_cdr(raw, connection.msgtype)
            assert msg.encoding == "mono16" and msg.header.frame_id == "g1/camera_optical_frame"
            got[by_stamp[stamp]] = np.frombuffer(bytes(msg.data), "<u2").reshape(msg.height, msg.width)
    assert got.keys() == plants.keys()
    assert all(np.array_equal(got[f], plants[f]) for f in plants)
    meta = (out / "metadata.yaml").read_text()
    assert "agrisim.bench" in meta and "plant_02" in meta


def test_a_rerendered_bench_keeps_its_plants(bench: Path, tmp_path: Path) -> None:
    """``agrisim render``: plants/ byte for byte; the saved scene it draws from keeps each
    plant's faces, so that a renderer on it draws the very plants/ of the run."""
    from agrisim.plugins.apps.render import RenderPlan

    out = tmp_path / "re"
    agrisim("render", str(bench), "--renderer", "raycast", "--out", str(out))
    for f in plant_images(bench):
        assert layout.image(out, layout.PLANTS, f).read_bytes() == layout.image(bench, layout.PLANTS, f).read_bytes()
    plan = RenderPlan(out, "raycast", {}, tmp_path / "unused", overwrite=False)
    renderer, camera = plan.renderer()
    assert [(p.name, p.plant, p.seed, p.xy) for p in renderer.scene.bench] == [
        (p["name"], p["plant"], p["seed"], (p["x"], p["y"])) for p in BENCH
    ]
    try:
        for f, ids in plant_images(bench).items():
            links = json.loads(layout.link_poses(out, f).read_text())
            poses = {r: {k: np.array(T) for k, T in v.items()} for r, v in links.items()}
            drawn = renderer.render(camera, np.array(plan.cameras["frames"][f]["world_T_camera"]), poses)
            assert drawn.plants is not None and np.array_equal(drawn.plants, ids), f
    finally:
        renderer.close()


def test_one_plant_gains_no_bench_keys(tmp_path: Path) -> None:
    """A run of one plant: no plants/, no ``bench`` in run.json or the scene, no ``plant`` in
    COCO, no ``plant_mask_path`` or ``plants`` in transforms.json, no plants in the recording."""
    from rerun.chunk import RrdReader

    from agrisim.plugins.formats.scene_glb import read_scene

    run = tmp_path / "one"
    agrisim("run", *FAST, "--out", str(run))
    agrisim("export", "coco", str(run))
    assert not (run / layout.PLANTS).exists()
    assert "bench" not in json.loads((run / layout.RUN_JSON).read_text())
    assert read_scene(run / layout.SCENE_GLB).bench == []
    coco = json.loads((run / "coco" / "annotations.json").read_text())
    assert "plants" not in coco and coco["annotations"] and not any("plant" in a for a in coco["annotations"])
    nerf = json.loads((run / layout.TRANSFORMS_JSON).read_text())
    assert "plants" not in nerf and not any("plant_mask_path" in f for f in nerf["frames"])
    assert not any(c.entity_path.endswith("/plants") for c in RrdReader(run / layout.RECORDING).stream())


@pytest.mark.parametrize(
    ("export", "harm", "says"),
    [
        ("coco", lambda run: _bench(run, [dict(BENCH[0], id=2)]), "run.json: malformed bench (plant 1 is"),
        ("nerfstudio", lambda run: _bench(run, "plant_01"), "run.json: malformed bench (not a list of plants)"),
        ("rosbag", lambda run: _bench(run, [dict(BENCH[0], seed="0")]), "run.json: malformed bench (plant 1 is"),
        ("nerfstudio", lambda run: layout.image(run, "plants", "g1_001").unlink(), "g1_001.png is missing"),
        ("coco", lambda run: layout.image(run, "plants", "g1_001").unlink(), "g1_001.png: the bench's frames are"),
    ],
    ids=["coco-id", "nerfstudio-rows", "rosbag-seed", "nerfstudio-image", "coco-image"],
)
def test_a_broken_bench_record_is_refused_in_one_line(export, harm, says, bench: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    run = Path(shutil.copytree(bench, tmp_path / "run"))
    harm(run)
    code, _, err = cli(["export", export, str(run), *([str(tmp_path / "out")] if export != "nerfstudio" else [])])
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert "Traceback" not in err and not (tmp_path / "out").exists()


def _bench(run: Path, rows: object) -> None:
    doc = json.loads((run / layout.RUN_JSON).read_text())
    (run / layout.RUN_JSON).write_text(json.dumps(dict(doc, bench=rows)))
