"""The dataset on disk holds exactly what was rendered: a small rendered run, read back."""

from __future__ import annotations

import json

import numpy as np
from PIL import Image

from agrisim.config import build_config
from agrisim.episode import Episode
from agrisim.plugins.formats.plant_asset import load_plant


def test_files_match_the_rendered_frames(tmp_path, frames):
    config = build_config(
        {
            "plant": "hydrangea",
            "render": {"labels": "organs"},
            "renderer": {"raycast": {"shadow_samples": 0}},
            "physics": {"backend": "kinematic"},
            "routine": {"setpoints": "1x2"},
            "camera": {"resolution": "320x180"},
            "output": {"out": str(tmp_path / "run"), "no_rrd": True},
        }
    )
    episode = Episode(config)
    episode.pm.register(frames)
    run, summary = episode.run()
    out = run.out_dir
    doc = json.loads((out / "run.json").read_text())
    # rewritten at every setpoint from cached pieces (files.json_text): still exactly what the
    # standard library's encoder writes
    for name in ("run.json", "cameras.json"):
        text = (out / name).read_text()
        assert text == json.dumps(json.loads(text), indent=2) + "\n", name
    assert sorted(doc["frames_complete"]) == sorted(frames.images) and len(frames.images) == summary.reached
    table = {lab["id"]: tuple(lab["color"]) for lab in doc["labels"]}
    assert {"leaf", "stem", "flower_white", "flower_purple"} <= {lab["name"] for lab in doc["labels"]}
    for name, images in frames.images.items():
        rgb = np.array(Image.open(out / "rgb" / f"{name}.png"))
        labels = np.array(Image.open(out / "labels" / f"{name}.png"))
        vis = np.array(Image.open(out / "labels_vis" / f"{name}.png").convert("RGB"))
        depth_mm = np.array(Image.open(out / "depth" / f"{name}.png"))
        assert np.array_equal(rgb, images.rgb)
        assert np.array_equal(labels, images.labels)
        for label_id in np.unique(labels):
            assert tuple(vis[labels == label_id][0]) == table[int(label_id)]
        assert depth_mm.dtype == np.uint16
        hit = images.depth > 0
        assert np.array_equal(depth_mm > 0, hit)
        assert np.max(np.abs(depth_mm[hit] / 1000.0 - images.depth[hit])) <= 0.0005 + 1e-6
    cams = json.loads((out / "cameras.json").read_text())
    assert sorted(cams["frames"]) == sorted(frames.images)
    # the ground-truth plant in world coordinates reads back as the scene's plant
    truth = run.scene.mesh(run.scene.plant)
    plant = load_plant(out / "scene" / "plant.glb", place=False)
    np.testing.assert_allclose(plant.mesh.vertices, truth.vertices, atol=1e-6)
    # triangles may be regrouped by material: compare them as a set, by their areas. The file's
    # float32 positions move each vertex by at most half an ulp, so a triangle's area by at most
    # its perimeter times that (small, thin blade triangles move by more than 1e-4 of it)
    ulp = float(np.spacing(np.float32(np.abs(truth.vertices).max())))
    corners = truth.vertices[truth.faces]
    perimeter = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).sum(axis=1)
    bound = float(perimeter.max()) * ulp
    assert np.abs(np.sort(plant.mesh.areas) - np.sort(truth.areas)).max() <= bound


def test_the_run_directory_is_written_whatever_plugins_are_loaded(tmp_path, monkeypatch):
    """The run directory's writer, the dataset sink, is loaded by every run: with only the
    backends a run needs chosen (AGRISIM_LOAD_PLUGINS names no sink: the Rerun recording is left
    out), run.json and cameras.json are still written, so --resume, recon, the exports and
    compare keep working."""
    monkeypatch.setenv("AGRISIM_LOAD_PLUGINS", "physics-kinematic,planner-ompl,plants-procedural")
    out = tmp_path / "run"
    config = build_config(
        {
            "physics": {"backend": "kinematic"},
            "renderer": {"backend": "none"},
            "routine": {"setpoints": "1x1"},
            "cell": {"arms": 1},
            "output": {"out": str(out), "no_rrd": True},
        }
    )
    episode = Episode(config)
    assert list(episode.registry.specs("sink")) == ["dataset"]
    run, summary = episode.run()
    doc = json.loads((out / "run.json").read_text())
    assert doc["status"] == summary.status == "complete"
    assert len(doc["results"]) == summary.setpoints == 1
