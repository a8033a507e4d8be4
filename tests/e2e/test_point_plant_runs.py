"""Point plants end to end: ``--as-points`` and a point-cloud file run the routine; every plant
pixel lies on the surface of the sphere of a drawn point (from the exact EXR depth and the saved
cloud), with that point's label; the dataset keeps the cloud as drawn and the truth."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import small_run
from scipy.spatial import cKDTree

from agrisim.evaluation.views import load_view
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json
from agrisim.plugins.formats.point_cloud import load_point_plant


@pytest.fixture(scope="module")
def sampled_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("points") / "run"
    return small_run(
        out,
        plant="hydrangea",
        points={"count": 30000},
        render={"labels": "organs", "depth_format": "exr"},
        routine={"setpoints": "1x2"},
    )


def _world_pixels(view) -> tuple[np.ndarray, np.ndarray]:
    """World points of a view's labelled pixels (from its depth) and their labels."""
    cam, T = view.camera, view.world_T_camera
    rows, cols = np.nonzero(view.images.labels)
    z = view.images.depth[rows, cols].astype(np.float64)
    p_cam = np.column_stack([(cols - cam.cx) / cam.fx * z, (rows - cam.cy) / cam.fy * z, z])
    return p_cam @ T[:3, :3].T + T[:3, 3], view.images.labels[rows, cols]


def test_as_points_pixels_lie_on_the_drawn_spheres_with_their_labels(sampled_run):
    cloud = load_point_plant(sampled_run / layout.PLANT_POINTS, place=False, up="z").points
    assert len(cloud) == 30000 and cloud.size > 0
    assert (sampled_run / layout.PLANT_GLB).is_file()  # the surface they were sampled from: the truth
    radius = cloud.size / 2
    tree = cKDTree(cloud.positions)
    cameras = json.loads((sampled_run / layout.CAMERAS_JSON).read_text())
    camera = camera_from_json(cameras["intrinsics"])
    checked = 0
    for frame, doc in cameras["frames"].items():
        view = load_view(sampled_run, frame, camera, np.asarray(doc["world_T_camera"], float))
        world, labels = _world_pixels(view)
        assert len(world) > 500
        d, i = tree.query(world, k=2)
        # on the surface of its sphere (the nearest centre is the sphere hit, or one just as near)
        assert np.all(np.abs(d[:, 0] - radius) < 2e-5)
        ties = np.abs(d[:, 1] - d[:, 0]) < 1e-6
        assert np.array_equal(labels[~ties], cloud.labels[i[~ties, 0]])
        checked += len(world)
    assert len(set(cloud.labels.tolist()) - {0}) >= 3  # hydrangea's organs came along
    metrics = json.loads((sampled_run / layout.METRICS_JSON).read_text())
    assert metrics["truth"]["surface"] is True
    assert metrics["labels"]["all"]["precision"]["5"] > 0.9
    assert checked > 2000


def test_a_point_cloud_file_runs_the_routine_and_is_its_own_truth(sampled_run, tmp_path):
    # the cloud a run drew, given back as a plant file: read with its label table and size
    plant_file = tmp_path / "hydrangea_points.ply"
    plant_file.write_bytes((sampled_run / layout.PLANT_POINTS).read_bytes())
    out = small_run(tmp_path / "run", plant=str(plant_file), render={"labels": "organs"}, routine={"setpoints": "1x2"})
    run = json.loads((out / layout.RUN_JSON).read_text())
    assert [lab["name"] for lab in run["labels"]] == [
        lab["name"] for lab in json.loads((sampled_run / layout.RUN_JSON).read_text())["labels"]
    ]
    assert not (out / layout.PLANT_GLB).exists()  # no surface: the points are the truth
    metrics = json.loads((out / layout.METRICS_JSON).read_text())
    assert metrics["truth"]["surface"] is False and metrics["truth"]["samples"] == 30000
    assert metrics["labels"]["all"]["pixels"] > 0
    assert metrics["labels"]["all"]["precision"]["5"] > 0.9
    drawn = load_point_plant(out / layout.PLANT_POINTS, place=False, up="z").points
    original = load_point_plant(sampled_run / layout.PLANT_POINTS, place=False, up="z").points
    assert drawn.size == original.size and np.array_equal(drawn.labels, original.labels)


def test_the_recording_shows_the_point_plant_with_its_radii(tmp_path):
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    from agrisim.config import build_config
    from agrisim.episode import Episode

    out = tmp_path / "run"
    cfg = build_config({
        "plant": "coltsfoot", "points": {"count": 2000, "size": 0.003},
        "physics": {"backend": "kinematic"}, "routine": {"setpoints": "1x1"}, "camera": {"resolution": "160x90"},
        "renderer": {"raycast": {"shadow_samples": 0}}, "recon": {"backend": "none"}, "output": {"out": str(out)},
    })  # fmt: skip
    _, summary = Episode(cfg).run()
    assert summary.status == "complete"
    drawn = load_point_plant(out / layout.PLANT_POINTS, place=False, up="z").points
    found = {}
    for chunk in RrdReader(out / layout.RECORDING).stream():
        if chunk.entity_path.lstrip("/") == "world/scene/plant/points" and chunk.is_static:
            rb = chunk.to_record_batch()
            for name in ("Points3D:positions", "Points3D:radii", "Points3D:colors"):
                if name in rb.schema.names:
                    found[name] = rb.column(name).to_pylist()[-1]
    positions = np.asarray(found["Points3D:positions"], np.float64)
    assert np.allclose(positions, drawn.positions, atol=1e-6)
    assert np.allclose(found["Points3D:radii"], 0.0015)
    assert len(found["Points3D:colors"]) == 2000
