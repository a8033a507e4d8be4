"""Point plants: spheres traced exactly (against a float64 brute force), labels, depth and
instances on analytic clouds, coverage against the disc-area formula, files in and out (with
trimesh and Open3D as second readers), sampling a mesh's opaque surface."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest

from agrisim.errors import UserError
from agrisim.plugins.formats.point_cloud import load_point_plant
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.points import PointTracer
from agrisim.plugins.render.raycast.tracing import SceneTracer, label_map
from agrisim.plugins.sinks.dataset.point_cloud import write_points_ply
from agrisim.scene.camera import CameraModel
from agrisim.scene.colour import srgb_to_linear
from agrisim.scene.model import Label, LabelTable, Material, Mesh, PointSet, Scene
from agrisim.scene.points import MAX_POINTS, as_points, check_count, check_size, default_size, sample_points

TABLE = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "leaf", (0, 255, 0)), Label(2, "stem", (96, 0, 128))])


def brute_force(
    rays: np.ndarray, centres: np.ndarray, radius: float, tfar: float = np.inf
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest sphere entry along each ray in float64: (t in units of the ray's direction, index)."""
    t_out = np.full(len(rays), np.inf)
    i_out = np.full(len(rays), -1)
    for k, ray in enumerate(rays.astype(np.float64)):
        o, d = ray[:3], ray[3:]
        a = d @ d
        oc = centres - o
        b = oc @ d / a  # the ray's closest approach to each centre, in t
        q = ((oc - b[:, None] * d) ** 2).sum(axis=1)  # squared distance there
        hit = (q <= radius * radius) & (b > 0)
        if not hit.any():
            continue
        t = b[hit] - np.sqrt((radius * radius - q[hit]) / a)
        ok = (t > 0) & (t <= tfar)
        if ok.any():
            j = np.argmin(np.where(ok, t, np.inf))
            t_out[k], i_out[k] = t[j], np.flatnonzero(hit)[j]
    return t_out, i_out


@pytest.mark.parametrize("radius", [1e-4, 2e-3, 0.03])
def test_spheres_are_hit_where_a_float64_brute_force_hits_them(radius):
    rng = np.random.default_rng(1)
    n = 3000
    centres = np.column_stack([rng.uniform(-0.1, 0.1, n), rng.uniform(-0.1, 0.1, n), rng.normal(0.3, radius, n)]) + [
        0.4,
        -0.2,
        0.0,
    ]
    # a spot of rays onto a patch dense enough that most hit (not a random mess of misses)
    k = 600
    target = centres[rng.integers(0, n, k)] + rng.normal(0, radius, (k, 3))
    origin = np.array([0.4, -0.2, 1.2]) + rng.normal(0, 0.05, (k, 3))
    rays = np.hstack([origin, (target - origin) * rng.uniform(0.5, 3.0, (k, 1))]).astype(np.float32)
    points = PointSet(centres, np.zeros((n, 3), np.uint8), np.ones(n, np.uint8), size=2 * radius)
    tracer = PointTracer(points)
    t, index = tracer.cast(rays)
    t_ref, i_ref = brute_force(rays, centres, radius)
    assert np.isfinite(t_ref).mean() > 0.3
    assert np.array_equal(np.isfinite(t), np.isfinite(t_ref))
    assert np.array_equal(index, i_ref)
    length = np.linalg.norm(rays[:, 3:].astype(np.float64), axis=1)
    hit = np.isfinite(t_ref)
    assert np.max(np.abs(t[hit] - t_ref[hit]) * length[hit]) < 1e-6  # metres along the ray

    # shadow rays: segments that end before, and after, the first sphere
    for frac in (0.5, 1.5):
        segments = rays.copy()
        end = np.where(hit, t_ref * frac, 1.0)
        segments[:, 3:] *= end[:, None].astype(np.float32)
        blocked = tracer.occluded(segments, 1.0)
        t_seg, _ = brute_force(segments, centres, radius, tfar=1.0)
        assert np.array_equal(blocked, np.isfinite(t_seg))
        assert blocked[hit].all() == (frac > 1)


def _plane(spacing: float, size: float, n_side: int = 61, z: float = 0.0, jitter: float = 0.0) -> PointSet:
    """A square grid of points in the plane z (labels 1 and 2 in halves, instances by column)."""
    g = (np.arange(n_side) - n_side // 2) * spacing
    x, y = np.meshgrid(g, g)
    rng = np.random.default_rng(0)
    p = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)]) + rng.normal(0, jitter, (x.size, 3))
    labels = np.where(p[:, 0] < 0, 1, 2).astype(np.uint8)
    instances = (np.arange(x.size) % n_side + 1).astype(np.uint16)
    colors = np.tile(np.array([40, 160, 40], np.uint8), (x.size, 1))
    return PointSet(p, colors, labels, instances, size=size)


def _looking_down(height: float) -> np.ndarray:
    """world_T_camera of a camera ``height`` above the origin looking down -z (OpenCV axes)."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[2, 3] = height
    return T


def _exact(points: PointSet, camera: CameraModel, T: np.ndarray) -> dict[str, np.ndarray]:
    scene = Scene(meshes=[], lights=[], labels=TABLE, points=points)
    tracer = SceneTracer(scene, None, RaycastOptions())
    return tracer.exact(camera, T, seg_mode="texture", label_map=label_map("organs"))


def test_labels_depth_and_instances_of_a_plane_of_points_are_the_nearest_spheres():
    camera = CameraModel(64, 48, 60.0, 60.0, 31.5, 23.5)
    points = _plane(spacing=0.004, size=0.005, n_side=41, jitter=0.001)
    T = _looking_down(0.3)
    out = _exact(points, camera, T)
    # every pixel's ray, from the near plane as the renderer casts it, by brute force
    opts = RaycastOptions()
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    d_cam = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u, float)], -1).reshape(
        -1, 3
    )
    d = d_cam @ T[:3, :3].T
    rays = np.hstack([T[:3, 3] + opts.near * d, d])
    t_ref, i_ref = brute_force(rays, points.positions, 0.5 * points.size)
    hit = np.isfinite(t_ref)
    assert 0.3 < hit.mean() < 1.0
    depth = out["depth"].ravel()
    assert np.array_equal(depth > 0, hit)
    assert np.max(np.abs(depth[hit] - (t_ref[hit] + opts.near))) < 1e-6  # planar z on the sphere's surface
    # the surface seen lies between the plane's points and a radius above them
    assert np.all(depth[hit] >= 0.3 - 0.5 * points.size - 0.004) and np.all(depth[hit] <= 0.3 + 0.004)
    labels = out["labels"].ravel()
    assert np.array_equal(labels[hit], points.labels[i_ref[hit]]) and not labels[~hit].any()
    assert np.array_equal(out["instances"].ravel()[hit], points.instances[i_ref[hit]])


def test_coverage_rises_with_point_size_as_the_disc_area_says():
    # a long lens far away: nearly orthographic, so a sphere covers pi r^2 of the plane's s^2 cells
    spacing = 0.002
    # pixels of 0.085 mm at 2 m, not a divisor of the spacing: discs fall on every phase of them
    camera = CameraModel(400, 400, 23456.0, 23456.0, 199.5, 199.5)
    T = _looking_down(2.0)
    covered = []
    for size in (0.0004, 0.0008, 0.0012, 0.0018, 0.0030):
        out = _exact(_plane(spacing, size, n_side=21), camera, T)
        share = float((out["labels"] > 0).mean())
        covered.append(share)
        if size < spacing:  # discs apart: the exact share of the cell
            assert share == pytest.approx(math.pi * (size / 2) ** 2 / spacing**2, rel=0.04)
    assert all(a < b for a, b in itertools.pairwise(covered))
    assert covered[-1] == 1.0  # overlapping spheres close the gaps


def test_point_files_read_back_exactly_and_a_second_reader_agrees(tmp_path):
    import trimesh

    pts = _plane(0.003, 0.002, n_side=11, jitter=0.0005)
    pts.positions[:, 2] += 0.1
    write_points_ply(tmp_path / "c.ply", pts, TABLE)
    plant = load_point_plant(tmp_path / "c.ply", place=False)
    back = plant.points
    assert np.array_equal(back.positions, pts.positions)
    assert np.array_equal(back.colors, pts.colors) and np.array_equal(back.labels, pts.labels)
    assert np.array_equal(back.instances, pts.instances) and back.size == pts.size
    assert plant.labels.to_json() == TABLE.to_json() and plant.organs
    raw = trimesh.load(tmp_path / "c.ply", process=False)
    assert np.allclose(raw.vertices, pts.positions, atol=0, rtol=0)
    placed = load_point_plant(tmp_path / "c.ply").points.positions
    assert placed[:, 2].min() == 0.0 and np.allclose((placed.min(0) + placed.max(0))[:2], 0.0)


def test_pcd_files_are_read_with_their_fields(tmp_path):
    o3d = pytest.importorskip("open3d")
    pts = _plane(0.003, 0.002, n_side=9)
    cloud = o3d.t.geometry.PointCloud(o3d.core.Tensor(pts.positions.astype(np.float32)))
    cloud.point["colors"] = o3d.core.Tensor(pts.colors)
    cloud.point["label"] = o3d.core.Tensor(pts.labels[:, None])
    cloud.point["instance"] = o3d.core.Tensor(pts.instances[:, None])
    o3d.t.io.write_point_cloud(str(tmp_path / "c.pcd"), cloud)
    plant = load_point_plant(tmp_path / "c.pcd", place=False, label_names={1: "leaf", 2: "stem"})
    assert np.allclose(plant.points.positions, pts.positions, atol=1e-7)
    assert np.array_equal(plant.points.labels, pts.labels) and np.array_equal(plant.points.instances, pts.instances)
    assert np.array_equal(plant.points.colors, pts.colors)
    assert [lab.name for lab in plant.labels.labels] == ["background", "leaf", "stem"]


def _ply(
    path,
    rows: str,
    props: str = "property float x\nproperty float y\nproperty float z\n",
    n: int | None = None,
    extra: str = "",
):
    count = n if n is not None else len([r for r in rows.splitlines() if r.strip()])
    path.write_text(f"ply\nformat ascii 1.0\nelement vertex {count}\n{props}{extra}end_header\n{rows}")
    return path


@pytest.mark.parametrize(
    "props, rows, names, expect",
    [
        ("property float x\nproperty float y\nproperty float z\n", "", None, "holds no points"),
        ("property float x\nproperty float y\nproperty float z\n", "0 0 0\nnan 0 1\n", None, "NaN or infinite"),
        ("property float x\nproperty float y\nproperty float z\n", "0 0 0\n0 inf 1\n", None, "NaN or infinite"),
        (
            "property float x\nproperty float y\nproperty float z\nproperty int label\n",
            "0 0 0 1\n0 0 1 300\n",
            None,
            "outside 0..255",
        ),
        (
            "property float x\nproperty float y\nproperty float z\nproperty int label\n",
            "0 0 0 1\n0 0 1 -1\n",
            None,
            "outside 0..255",
        ),
        (
            "property float x\nproperty float y\nproperty float z\nproperty uchar label\n",
            "0 0 0 1\n0 0 1 7\n",
            {1: "leaf"},
            "does not name",
        ),
        # without names, the default table: 0 background and 1 plant, nothing guessed
        (
            "property float x\nproperty float y\nproperty float z\nproperty uchar label\n",
            "0 0 0 1\n0 0 1 250\n",
            None,
            r"\[250\] that the default table",
        ),
        ("property float x\nproperty float y\n", "0 0\n", None, "x, y and z"),
    ],
)
def test_bad_point_files_are_refused_with_one_line(tmp_path, props, rows, names, expect):
    path = _ply(tmp_path / "bad.ply", rows, props)
    with pytest.raises(UserError, match=expect) as info:
        load_point_plant(path, label_names=names)
    assert "\n" not in str(info.value)


def test_ids_the_header_table_of_an_agrisim_ply_does_not_name_are_refused(tmp_path):
    pts = _plane(0.003, 0.002, n_side=4, jitter=0.0)
    pts.labels[:] = 1
    pts.labels[5] = 42  # in no table
    write_points_ply(tmp_path / "c.ply", pts, TABLE)
    with pytest.raises(UserError, match=r"\[42\] that the table in its header does not name") as info:
        load_point_plant(tmp_path / "c.ply")
    assert "\n" not in str(info.value)
    # named by the run, the same file reads
    names = {lab.id: lab.name for lab in TABLE.labels if lab.id} | {42: "fruit"}
    assert 42 in {lab.id for lab in load_point_plant(tmp_path / "c.ply", label_names=names).labels.labels}


def test_a_ply_mesh_is_not_taken_for_a_cloud(tmp_path):
    path = tmp_path / "mesh.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    )
    with pytest.raises(UserError, match="is a mesh"):
        load_point_plant(path)


def test_sizes_and_counts_outside_their_limits_are_refused():
    for bad in (0, -1e-3, float("nan"), float("inf"), 2.0):
        with pytest.raises(UserError, match="--point-size"):
            check_size(bad)
    for bad in (0, -5, MAX_POINTS + 1):
        with pytest.raises(UserError, match="--as-points"):
            check_count(bad)
    check_size(0.002)
    check_count(MAX_POINTS)


def _card() -> Mesh:
    """A 10 cm square card whose left half is cut away by opacity; the label texture names the
    top half 1 and the bottom 2; the albedo is red at the top and blue at the bottom."""
    albedo = np.zeros((4, 4, 4), np.uint8)
    albedo[:2, :, :3] = (200, 30, 30)
    albedo[2:, :, :3] = (30, 30, 200)
    albedo[:, 2:, 3] = 255  # the right half is opaque (u >= 0.5)
    labels = np.zeros((4, 4), np.uint8)
    labels[:2] = 1
    labels[2:] = 2
    mat = Material("card", color=(1.0, 1.0, 1.0, 1.0), albedo=albedo, labels=labels, alpha_mode="MASK")
    v = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]], float)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # v grows downwards: y = 0.1 is the top
    return Mesh(
        "card", v, np.array([[0, 1, 2], [0, 2, 3]]), [mat], np.zeros(2, np.int32), uv, np.array([5, 5], np.uint16)
    )


def test_sampled_points_lie_on_opaque_texels_with_their_colour_label_and_instance():
    pts = sample_points(_card(), 4000, seed=3)
    assert len(pts) == 4000
    p = pts.positions
    assert np.all(p[:, 0] >= 0.05 - 1e-12)  # none on the cut-away half
    top = p[:, 1] > 0.05
    assert np.all(pts.labels[top] == 1) and np.all(pts.labels[~top] == 2)
    assert np.all(pts.colors[top] == (200, 30, 30)) and np.all(pts.colors[~top] == (30, 30, 200))
    assert np.all(pts.instances == 5)
    assert 0.4 < top.mean() < 0.6
    again = sample_points(_card(), 4000, seed=3)
    assert np.array_equal(again.positions, p)


def test_default_size_covers_a_randomly_sampled_surface():
    # uniform points on a 10 cm square seen head-on: the share left uncovered is about 1%
    rng = np.random.default_rng(0)
    n = 5000
    p = np.column_stack([rng.uniform(0, 0.1, n), rng.uniform(0, 0.1, n), np.zeros(n)])
    size = default_size(p)
    grid = np.stack(np.meshgrid(np.linspace(0.02, 0.08, 120), np.linspace(0.02, 0.08, 120)), -1).reshape(-1, 2)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(p[:, :2]).query(grid)
    uncovered = float((d > size / 2).mean())
    assert 0.002 < uncovered < 0.03


def test_as_points_keeps_the_mesh_as_truth_and_refuses_misuse():
    from agrisim.scene.model import Plant

    plant = Plant("card", _card(), TABLE)
    drawn = as_points(plant, 500, None)
    assert drawn.points is not None and len(drawn.points) == 500 and drawn.points.size > 0
    assert drawn.mesh is plant.mesh
    with pytest.raises(UserError, match="already a point cloud"):
        as_points(drawn, 100, None)
    with pytest.raises(UserError, match="applies to point plants"):
        as_points(plant, None, 0.002)


def test_thickness_is_twice_the_normal_offset_of_points_off_a_surface():
    from agrisim.evaluation.metrics import GroundTruth, SurfaceDistance, thickness_mm

    square = Mesh(
        "square",
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.1,
        np.array([[0, 1, 2], [0, 2, 3]]),
        [Material("m", label=1)],
        np.zeros(2, np.int32),
    )
    truth = GroundTruth.sample(square, 1000)
    rng = np.random.default_rng(0)
    h = 0.0015  # two sheets 1.5 mm either side of the plane, as spheres of 3 mm would show it
    p = np.column_stack(
        [rng.uniform(0.01, 0.09, 400), rng.uniform(0.01, 0.09, 400), np.where(rng.random(400) < 0.5, h, -h)]
    )
    offsets = SurfaceDistance(truth).normal_offsets(p)
    assert np.allclose(np.abs(offsets), h, atol=1e-7)
    assert np.allclose(
        offsets * np.sign(p[:, 2]), offsets[0] * np.sign(p[0, 2])
    )  # one side positive, the other negative
    assert thickness_mm(offsets) == pytest.approx(2 * h * 1e3, abs=1e-4)


def test_sampled_points_take_the_vertex_colour_there():
    """A vertex colour running from white at x = 0 to (0.5, 0.25, 1) at x = 0.1 multiplies each
    point's albedo in linear light, as the renderers do at that place on the card."""
    card = _card()
    far = np.array([0.5, 0.25, 1.0])
    tinted = dataclasses.replace(card, colors=1.0 + (far - 1.0) * (card.vertices[:, :1] / 0.1))
    plain, pts = sample_points(card, 2000, seed=4), sample_points(tinted, 2000, seed=4)
    np.testing.assert_array_equal(pts.positions, plain.positions)
    expected = srgb_to_linear(plain.colors / 255.0) * (1.0 + (far - 1.0) * (pts.positions[:, :1] / 0.1))
    np.testing.assert_allclose(srgb_to_linear(pts.colors / 255.0), expected, atol=0.004)  # 8-bit steps
