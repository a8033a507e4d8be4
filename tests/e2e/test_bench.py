"""A bench of plants: several plants in their own pots on one table, each pixel's plant known.

Truth: a second ray caster (Open3D's RaycastingScene) over each plant grown alone and moved to
its pot, one geometry per plant, so that the plant a ray meets first is known without agrisim's
joined mesh or its renderer; the same plant rendered alone; the hemisphere's aim points (each
gantry view looks at one plant's); and the refusals' messages.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
from PIL import Image

from agrisim.config import RunConfig, build_config
from agrisim.evaluation.views import load_depth
from agrisim.files import layout
from agrisim.plant_choice import resolve_plant
from agrisim.registry import Registry, make_plugin_manager
from agrisim.robot.cell import soil_pose
from agrisim.validation import open_rig

#: two ray casters (float32 Embree here, Open3D's there) agree on a hit's distance within this, m
TIE = 1e-4
FAST = ["--physics", "kinematic", "--no-rrd", "--shadow-samples", "0", "--recon", "none"]


def read_png(path: Path) -> np.ndarray:
    return np.array(Image.open(path))


def images(run: Path, folder: str) -> dict[str, np.ndarray]:
    return {p.stem: read_png(p) for p in sorted((run / folder).glob("*.png"))}


def bench_toml(tmp_path: Path, plants: list[dict[str, object]]) -> Path:
    rows = "".join(
        "[[bench.plants]]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in p.items()) + "\n" for p in plants
    )
    path = tmp_path / "bench.toml"
    path.write_text(rows)
    return path


def test_a_gantry_scans_every_plant_of_a_bench(tmp_path: Path, cli) -> None:  # noqa: ANN001
    """``--rig gantry --bench 2x3``: each plant's hemisphere in turn (each view aimed at one
    plant's aim point), every plant seen, each pixel's plant where and only where a plant is,
    and each leaf instance on one plant only."""
    out = tmp_path / "run"
    code, stdout, err = cli(
        [
            "run",
            "--rig",
            "gantry",
            "--bench",
            "2x3",
            "--setpoints",
            "1x3",
            "--resolution",
            "64x48",
            *FAST,
            "--out",
            str(out),
        ]
    )
    assert code == 0, err
    note = next(line for line in stdout.splitlines() if "a bench of 6" in line)
    assert sorted(note.split("in the order ")[1].split(";")[0].split(", ")) == [f"plant_{k:02d}" for k in range(1, 7)]
    run = json.loads((out / layout.RUN_JSON).read_text())
    assert all(r["reached"] for r in run["results"]) and len(run["results"]) >= 12, run["results"]
    cameras = json.loads((out / layout.CAMERAS_JSON).read_text())["frames"]
    config = RunConfig()
    aims = [
        np.array([(c - 1) * 0.5, (r - 0.5) * 0.5, config.cell.table_height + config.routine.aim_height])
        for r in range(2)
        for c in range(3)
    ]
    for frame, cam in cameras.items():
        T = np.array(cam["world_T_camera"])
        # the distance of each aim point from the optical axis: one of them lies on it
        off = [np.linalg.norm(np.cross(a - T[:3, 3], T[:3, 2])) for a in aims]
        assert min(off) < 1e-6, (frame, off)
    plants, labels, instances = images(out, "plants"), images(out, "labels"), images(out, "instances")
    assert plants.keys() == labels.keys() == cameras.keys()
    seen = set()
    for frame, ids in plants.items():
        assert ids.dtype == np.uint16
        assert np.array_equal(ids > 0, labels[frame] > 0), frame
        seen |= set(np.unique(ids).tolist())
        leaf = instances[frame]
        for i in np.unique(leaf[leaf > 0]):
            assert len(np.unique(ids[leaf == i])) == 1, (frame, i)
    assert seen == set(range(7))


def test_touching_plants_split_at_their_true_boundary(tmp_path: Path, cli) -> None:  # noqa: ANN001
    """Two plants whose leaves interleave: at every pixel of either, the plant is the one whose
    surface a ray through the pixel meets first, by Open3D's ray caster over each plant grown
    alone (where that first surface is the one seen: not cut away by a leaf card's opacity)."""
    spots = [{"x": -0.1, "y": 0.0}, {"x": 0.1, "y": 0.02}]
    out = tmp_path / "run"
    args = ["run", "--config", str(bench_toml(tmp_path, spots)), "--setpoints", "1x2", "--resolution", "160x120"]
    code, _, err = cli([*args, "--depth-format", "exr", *FAST, "--out", str(out)])
    assert code == 0, err
    registry = Registry(make_plugin_manager())
    soil = soil_pose(open_rig(RunConfig())[1])[2, 3]
    scenes = []  # each plant a ray caster of its own: where both are hit within TIE, no plant is first
    for k, spot in enumerate(spots):
        alone = resolve_plant(registry, build_config({"plants": {"indian_cress": {"seed": k}}}))
        v = alone.mesh.vertices + np.array([spot["x"], spot["y"], soil])
        scenes.append(o3d.t.geometry.RaycastingScene())
        scenes[-1].add_triangles(v.astype(np.float32), alone.mesh.faces.astype(np.uint32))
    cams = json.loads((out / layout.CAMERAS_JSON).read_text())
    K = np.array(cams["intrinsics"]["K"])
    compared = agree = boundary = 0
    for frame, cam in cams["frames"].items():
        ids = read_png(layout.image(out, "plants", frame)).astype(np.int64)
        depth = load_depth(out, frame)
        T = np.array(cam["world_T_camera"])
        v, u = np.mgrid[0 : ids.shape[0], 0 : ids.shape[1]]
        d = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(u.shape)], -1) @ T[:3, :3].T
        o = np.broadcast_to(T[:3, 3], d.shape)
        rays = o3d.core.Tensor(np.concatenate([o, d], -1).astype(np.float32))
        hits = np.stack([scene.cast_rays(rays)["t_hit"].numpy() for scene in scenes])  # planar: d's z is 1
        t, owner = hits.min(axis=0), hits.argmin(axis=0) + 1
        tie = np.isclose(
            hits[0], hits[1], rtol=0.0, atol=TIE
        )  # the two plants' surfaces cross here: either may be first
        first_seen = (ids > 0) & np.isfinite(t) & (np.abs(t - depth) < TIE) & ~tie
        compared += int(first_seen.sum())
        agree += int((ids[first_seen] == owner[first_seen]).sum())
        boundary += int(((ids[:, 1:] * ids[:, :-1]) == 2).sum() + ((ids[1:] * ids[:-1]) == 2).sum())
        assert first_seen.sum() > 0.3 * (ids > 0).sum(), frame
    assert boundary >= 20, boundary  # the views do show the two plants meeting
    assert agree == compared and compared > 1000, (agree, compared)


def test_a_plant_far_from_its_neighbour_is_labelled_as_alone(tmp_path: Path, cli) -> None:  # noqa: ANN001
    """A bench's first plant with its neighbour far off: its pixels, labels, leaf instances and
    depth are the same plant's alone (same seed, same views)."""
    bench, alone = tmp_path / "bench", tmp_path / "alone"
    common = ["--setpoints", "1x2", "--resolution", "96x72", "--labels", "organs", *FAST]
    toml = bench_toml(tmp_path, [{"x": 0.0, "y": 0.0}, {"x": 0.0, "y": -1.3, "plant": "boxwood"}])
    assert cli(["run", "--config", str(toml), *common, "--out", str(bench)])[0] == 0
    assert cli(["run", *common, "--out", str(alone)])[0] == 0
    frames = images(alone, "labels")
    assert frames.keys() == images(bench, "plants").keys() and len(frames) == 4
    for frame, labels in frames.items():
        ids = read_png(layout.image(bench, "plants", frame))
        mine = ids == 1
        assert np.array_equal(mine, labels > 0), frame
        for folder in ("labels", "instances"):
            a, b = read_png(layout.image(alone, folder, frame)), read_png(layout.image(bench, folder, frame))
            assert np.array_equal(a[mine], b[mine]), (frame, folder)
        assert np.array_equal(load_depth(alone, frame)[mine], load_depth(bench, frame)[mine]), frame


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--bench", "2x2", "--spacing", "0.1"], "plant_01 and plant_02 overlap: their pots stand 0.100 m apart"),
        (["--bench", "0x2"], "bench '0x2': R and C must be between 1 and 100"),
        (["--spacing", "0.6"], "[bench] takes a grid (--bench RxC) or a list of [[bench.plants]]"),
        (["--bench", "1x2", "--rig", "turntable"], "rig 'turntable' holds one plant"),
        (["--bench", "3x3", "--spacing", "0.6"], "bench: its table (1.70 x 1.70 m) would reach the rig's r1_stand"),
        (["--bench", "1x2", "--as-points", "2000"], "bench: plants are drawn as meshes"),
        (["--bench", "1x2", "--renderer", "pybullet"], "or a bench's plants apart ("),
        (["--bench", "1x3", "--rig", "gantry", "--set", "rig.gantry.travel_x=0.8"], "beyond the gantry's travel"),
        ([{"x": 0.0, "y": 0.0}, {"x": 0.5, "y": 0.0, "plant": "no_such"}], "bench plant_02: unknown plant 'no_such'"),
    ],
    ids=["overlap", "grid", "spacing-alone", "turntable", "stand", "points", "renderer", "travel", "species"],
)
def test_bad_benches_are_refused_in_one_line(args: list, says: str, tmp_path: Path, cli) -> None:  # noqa: ANN001
    if isinstance(args[0], dict):
        args = ["--config", str(bench_toml(tmp_path, args))]
    out = tmp_path / "never"
    small = ["--physics", "kinematic", "--no-rrd", "--setpoints", "1x2", "--resolution", "32x24"]
    code, _, err = cli(["run", *args, *small, "--out", str(out)])
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert "Traceback" not in err and not out.exists()
