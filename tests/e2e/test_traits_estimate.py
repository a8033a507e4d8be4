"""A run's plant as a phenotyping pipeline sees it (agrisim.plugins.apps.traits.estimate): each leaf's
points fused from the views by its instance mask lie on that very leaf of the ground-truth mesh
(scene/plant.glb), by id, within the dataset's millimetre depth; a tilted cut-out card's area,
inclination, azimuth and height come back from its views; ``agrisim traits RUN --measure``
scores them against the truth; a run without instance masks is refused."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
from conftest import LEAF_LABELS, leaf_card, small_run
from test_cli_errors import assert_one_line_error, snapshot

from agrisim.errors import UserError
from agrisim.files import layout
from agrisim.files.rundir import read_json
from agrisim.plugins.apps.traits.estimate import fuse_views, plant_T_world
from agrisim.plugins.formats.plant_asset import load_plant


@pytest.fixture(scope="module")
def run(saved_runs) -> Path:  # noqa: ANN001
    return saved_runs.get(plant="coltsfoot", seed=4)


def test_each_leafs_points_lie_on_that_leaf(run: Path) -> None:
    """Every fused point within 0.75 mm of its own leaf's true triangles (measured at most 0.52:
    the depth's whole millimetres, half of one along the ray, and the 1 mm voxels' means)."""
    clouds = fuse_views(run).leaves
    mesh = load_plant(run / layout.PLANT_GLB, place=False).mesh  # the world's frame
    assert mesh.face_instance is not None
    assert clouds and set(clouds) <= set(np.unique(mesh.face_instance).tolist()) - {0}
    T = plant_T_world(read_json(run / layout.RUN_JSON, ""))
    vertices = o3d.core.Tensor((mesh.vertices @ T[:3, :3].T + T[:3, 3]).astype(np.float32))
    for leaf, points in clouds.items():
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(vertices, o3d.core.Tensor(mesh.faces[mesh.face_instance == leaf].astype(np.uint32)))
        distance = scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
        assert distance.max() < 0.75e-3, (leaf, distance.max())
        # one point a voxel: no two closer than the grid allows
        assert len(np.unique(np.floor(points / 1e-3), axis=0)) == len(points)


def test_a_run_without_instance_masks_is_refused(run: Path, tmp_path: Path, cli) -> None:
    bare = tmp_path / "bare"
    shutil.copytree(run, bare)
    shutil.rmtree(bare / "instances")
    with pytest.raises(UserError, match="no instance masks"):
        fuse_views(bare)
    before = snapshot(bare)
    code, _, err = cli(["traits", str(bare), "--measure"])
    assert_one_line_error(code, err, ["no instance masks", "instances/"])
    assert snapshot(bare) == before, "something was written"


def test_a_tilted_cut_out_card_is_measured_from_the_views(tmp_path: Path, cli) -> None:
    """A user's glTF card, 8 cm square with its left half cut away, tilted 30 degrees, seen by
    36 views (3x6 setpoints an arm) at 320x180, measured by ``agrisim traits RUN --measure``: the leaf's inclination
    within 1 degree of its tilt, its azimuth within 2 of the truth's 270, the ball-pivoting
    surface's area between 75% and 101% of the opaque half (measured 88%: what the views saw,
    less half a point spacing along the outline), and the plant's height (the card rests on the
    soil, its top edge 8 sin 30 = 4 cm up) within 1 mm (the depth's whole millimetres)."""
    from agrisim.plugins.sinks.dataset.glb import export_glb

    alpha = np.zeros((64, 64), np.uint8)
    alpha[:, 32:] = 255
    export_glb(leaf_card(0.08, alpha, 30.0, at=(0.0, 0.0, 0.12)), tmp_path / "card.glb", LEAF_LABELS)
    run = small_run(tmp_path / "run", plant=str(tmp_path / "card.glb"), routine={"setpoints": "3x6"})
    code, stdout, err = cli(["traits", str(run), "--measure"])
    assert code == 0, err
    measured = json.loads((run / "traits.json").read_text())["measured"]
    assert measured["depth"] == "truth" and measured["views"] == 36
    (leaf,) = measured["leaves"]
    assert leaf["id"] == 1
    assert leaf["inclination_deg"] == pytest.approx(30.0, abs=1.0)
    assert leaf["azimuth_deg"] == pytest.approx(270.0, abs=2.0)
    assert 0.75 * 0.0032 < leaf["area_m2"] < 1.01 * 0.0032
    assert measured["height_m"] == pytest.approx(0.08 * np.sin(np.radians(30.0)), abs=1e-3)
    errors = measured["errors"]
    assert (errors["leaves_seen"], errors["leaves_there"], errors["clusters"], errors["clusters_one_leaf"]) == (
        1,
        1,
        1,
        1,
    )
    assert "1 of 1 leaves seen" in stdout
