"""The lab scene: furniture drawn where the physics bodies are, the plant on its soil, the
paper's lights and the paper's PCG clutter rules (checked with this file's own geometry)."""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.config import CellConfig
from agrisim.plugins.rigs.paper.cell import build_cell
from agrisim.plugins.rooms.lab import clutter
from agrisim.plugins.rooms.lab import room as lab
from agrisim.robot.cell import Box, Cylinder
from agrisim.scene.model import Label, LabelTable, Material, Mesh, Plant

# ---------------------------------------------------------------------------------------------
# fixtures: a tiny synthetic plant (a textured card with organ labels 2 and 3)
# ---------------------------------------------------------------------------------------------


def _card_plant() -> Plant:
    albedo = np.zeros((8, 8, 4), np.uint8)
    albedo[..., 1] = 180
    albedo[..., 3] = 255
    albedo[:, :2, 3] = 0  # a cut-out strip
    labels = np.zeros((8, 8), np.uint8)
    labels[:4, 2:] = 2
    labels[4:, 2:] = 3
    leaf = Material("leaf", albedo=albedo, labels=labels, alpha_mode="MASK")
    stem = Material("stem", label=3)
    V = np.array([[-0.05, -0.05, 0.0], [0.05, -0.05, 0.0], [0.05, 0.05, 0.12], [-0.05, 0.05, 0.12], [0.0, 0.0, 0.2]])
    F = np.array([[0, 1, 2], [0, 2, 3], [2, 3, 4]])
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0], [0.5, 0.5]])
    mesh = Mesh("card", V, F, [leaf, stem], np.array([0, 0, 1]), uv, np.array([1, 1, 2]))
    table = LabelTable(
        [Label(0, "background", (0, 0, 0)), Label(2, "leaf", (0, 255, 0)), Label(3, "stem", (80, 0, 80))]
    )
    return Plant("card", mesh, table, organs=True)


@pytest.fixture(scope="module")
def plant() -> Plant:
    return _card_plant()


@pytest.fixture(scope="module")
def scene(cell, plant):
    return lab.build_scene(cell, plant, pcg_seed=42)


DRAWN = ("table", "pot", "r1_stand", "r2_stand")


def _physics_bounds(ob) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(ob, Box):
        h = np.asarray(ob.size) / 2
    else:
        assert isinstance(ob, Cylinder)
        h = np.array([ob.radius, ob.radius, ob.height / 2])
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    world = corners @ ob.world_T[:3, :3].T + ob.world_T[:3, 3]
    return world.min(axis=0), world.max(axis=0)


# ---------------------------------------------------------------------------------------------
# furniture and plant
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "cfg",
    [
        CellConfig(),
        CellConfig(
            arm_distance=1.6,
            stand_height=0.6,
            stand_size=0.55,
            table_height=0.7,
            table_size=0.8,
            pot_radius=0.13,
            pot_height=0.2,
        ),
    ],
    ids=["paper", "other"],
)
def test_furniture_meshes_are_the_physics_bodies(cfg, plant):
    cell = build_cell(cfg)
    scene = lab.build_scene(cell, plant)
    names = {m.name for m in scene.meshes}
    assert "plant_keepout" not in names  # a planning volume, never drawn
    for ob in cell.obstacles:
        if ob.name not in DRAWN:
            continue
        lo, hi = _physics_bounds(ob)
        v = scene.mesh(ob.name).vertices
        np.testing.assert_allclose(v.min(axis=0), lo, atol=1e-9, rtol=0, err_msg=ob.name)
        np.testing.assert_allclose(v.max(axis=0), hi, atol=1e-9, rtol=0, err_msg=ob.name)
    # the pot's polygon lies within the physical cylinder (inscribed) and close to it
    pot = next(ob for ob in cell.obstacles if ob.name == "pot")
    v = scene.mesh("pot").vertices
    r = np.hypot(v[:, 0] - pot.world_T[0, 3], v[:, 1] - pot.world_T[1, 3])
    assert r.max() <= pot.radius + 1e-9
    assert r.max() >= pot.radius - 1e-9


def test_plant_stands_on_the_soil_in_the_pot(cell, plant, scene):
    pot = next(ob for ob in cell.obstacles if ob.name == "pot")
    top = pot.world_T[2, 3] + pot.height / 2
    soil = scene.mesh("soil").vertices
    soil_z = soil[:, 2]
    assert np.ptp(soil_z) < 1e-12
    assert top - 0.03 < soil_z[0] < top  # inset slightly below the rim
    p = scene.mesh(scene.plant).vertices
    low = p[np.isclose(p[:, 2], p[:, 2].min(), atol=1e-12)]
    np.testing.assert_allclose(low[:, 2], soil_z[0], atol=1e-12)
    rad = np.hypot(low[:, 0] - pot.world_T[0, 3], low[:, 1] - pot.world_T[1, 3])
    assert np.all(rad < pot.radius)
    # a pure translation of the plant frame
    shift = p - plant.mesh.vertices
    np.testing.assert_allclose(shift, np.broadcast_to(shift[0], p.shape), atol=1e-12)
    np.testing.assert_array_equal(scene.mesh("plant").face_instance, plant.mesh.face_instance)


def test_plant_label_mode_maps_every_organ_to_one(plant, scene):
    assert scene.plant == "plant"
    assert [(lab_.id, lab_.name, lab_.color) for lab_ in scene.labels.labels] == [
        (0, "background", (0, 0, 0)),
        (1, "plant", (0, 255, 0)),
    ]
    mesh = scene.mesh("plant")
    for new, old in zip(mesh.materials, plant.mesh.materials, strict=True):
        if old.labels is None:
            assert new.labels is None and new.label == (1 if old.label else 0)
        else:
            assert set(np.unique(new.labels)) <= {0, 1}
            np.testing.assert_array_equal(new.labels, (old.labels > 0).astype(np.uint8))
        assert new.albedo is old.albedo and new.alpha_mode == old.alpha_mode
    # the plant's own materials are not touched
    assert set(np.unique(plant.mesh.materials[0].labels)) == {0, 2, 3}
    assert plant.mesh.materials[1].label == 3


def test_organ_label_mode_keeps_the_plants_ids(cell, plant):
    scene = lab.build_scene(cell, plant, labels="organs")
    assert [lab_.id for lab_ in scene.labels.labels] == [0, 2, 3]
    assert scene.labels.by_name("stem").color == (80, 0, 80)
    mesh = scene.mesh("plant")
    np.testing.assert_array_equal(mesh.materials[0].labels, plant.mesh.materials[0].labels)
    assert mesh.materials[1].label == 3
    with pytest.raises(ValueError, match="labels"):
        lab.build_scene(cell, plant, labels="leaves")


def test_everything_but_the_plant_is_background_and_budgets_hold(scene):
    faces = 0
    for m in scene.meshes:
        for mat in m.materials:
            if mat.albedo is not None:
                assert max(mat.albedo.shape[:2]) <= 512
                assert m.uvs is not None
        if m.name == scene.plant:
            continue
        faces += len(m.faces)
        assert all(mat.label == 0 and mat.labels is None for mat in m.materials), m.name
        # outward-facing geometry has no degenerate triangles
        assert m.areas.min() > 1e-10, m.name
    assert faces < 8000
    names = [m.name for m in scene.meshes]
    assert len(names) == len(set(names))
    assert {"floor", "walls", "ceiling", "table", "pot", "soil", "r1_stand", "r2_stand", "plant"} <= set(names)


def test_room_encloses_everything(cell, scene):
    room = clutter.room_for(cell)
    assert room.size == (10.0, 8.0) and room.height == 3.0
    xmin, xmax, ymin, ymax = room.bounds
    for m in scene.meshes:
        v = m.vertices
        assert v[:, 0].min() >= xmin - 1e-9 and v[:, 0].max() <= xmax + 1e-9, m.name
        assert v[:, 1].min() >= ymin - 1e-9 and v[:, 1].max() <= ymax + 1e-9, m.name
        assert v[:, 2].min() >= -1e-9 and v[:, 2].max() <= room.height + 1e-9, m.name
    assert np.isclose(scene.mesh("floor").areas.sum(), 80.0)
    assert np.isclose(scene.mesh("walls").areas.sum(), 2 * (10 + 8) * 3)
    # floor and ceiling face into the room
    f = scene.mesh("floor")
    a, b, c = f.vertices[f.faces[0]]
    assert np.cross(b - a, c - a)[2] > 0
    f = scene.mesh("ceiling")
    a, b, c = f.vertices[f.faces[0]]
    assert np.cross(b - a, c - a)[2] < 0


# ---------------------------------------------------------------------------------------------
# lights
# ---------------------------------------------------------------------------------------------


def test_four_lights_two_ceiling_two_on_the_stands(cell, scene):
    assert len(scene.lights) == 4
    plant_v = scene.mesh("plant").vertices
    plant_c = (plant_v.min(axis=0) + plant_v.max(axis=0)) / 2
    ceiling = [lt for lt in scene.lights if lt.position[2] > 2.5]
    stands = [lt for lt in scene.lights if lt.position[2] <= 2.5]
    assert len(ceiling) == 2 and len(stands) == 2
    for lt in scene.lights:
        assert lt.kind == "area" and 0.1 <= lt.radius <= 0.35 and lt.intensity > 0
        assert np.isclose(np.linalg.norm(lt.direction), 1.0)
    for lt in ceiling:
        assert lt.direction[2] < -0.9
        assert lt.position[2] < 3.0
    boxes = {ob.name: ob for ob in cell.obstacles}
    for lt, name in zip(stands, ("r1_stand", "r2_stand"), strict=True):
        stand = boxes[name]
        c, h = stand.world_T[:3, 3], np.asarray(stand.size) / 2
        assert np.all(np.abs(lt.position[:2] - c[:2]) <= h[:2])  # above the stand
        assert lt.position[2] >= c[2] + h[2]
        to_plant = (plant_c - lt.position) / np.linalg.norm(plant_c - lt.position)
        assert np.dot(lt.direction, to_plant) > 0.99
    # the plant is well lit: each light alone gives a sizeable irradiance there
    for lt in scene.lights:
        d = plant_c - lt.position
        dist = np.linalg.norm(d)
        assert lt.intensity * np.dot(lt.direction, d / dist) / dist**2 > 0.25


# ---------------------------------------------------------------------------------------------
# PCG clutter, checked with this file's own footprint geometry
# ---------------------------------------------------------------------------------------------

SIZES = {"cabinet": (0.9, 0.5), "pallet": (1.2, 0.8)}
DRUM_R = 0.29
RATES = {"cabinet": 0.1, "pallet": 0.5, "drum": 0.75}
RANK = {"cabinet": 0, "pallet": 1, "drum": 2}
ROOM = clutter.Room()


def _shape(item):
    """Footprint: ("circle", centre, radius) for drums, ("poly", 4 x 2 corners) otherwise."""
    if item.kind == "drum":
        return ("circle", np.array([item.x, item.y]), DRUM_R)
    w, d = SIZES[item.kind]
    local = np.array([[-w, -d], [w, -d], [w, d], [-w, d]]) / 2
    c, s = np.cos(item.yaw), np.sin(item.yaw)
    return ("poly", local @ np.array([[c, -s], [s, c]]).T + (item.x, item.y))


def _polys_share_area(p: np.ndarray, q: np.ndarray, tol: float) -> bool:
    """Separating axis test on two convex polygons."""
    for poly in (p, q):
        edges = np.roll(poly, -1, axis=0) - poly
        for nx, ny in np.column_stack([-edges[:, 1], edges[:, 0]]):
            axis = np.array([nx, ny]) / np.hypot(nx, ny)
            a, b = p @ axis, q @ axis
            if a.max() <= b.min() + tol or b.max() <= a.min() + tol:
                return False
    return True


def _circle_polygon_share_area(c: np.ndarray, r: float, poly: np.ndarray, tol: float) -> bool:
    edges = np.roll(poly, -1, axis=0) - poly
    rel = c - poly
    cross = edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0]
    if np.all(cross > 0) or np.all(cross < 0):  # centre inside
        return True
    t = np.clip((rel * edges).sum(axis=1) / (edges * edges).sum(axis=1), 0.0, 1.0)
    dist = np.linalg.norm(rel - t[:, None] * edges, axis=1)
    return bool(dist.min() < r - tol)


def _share_area(a, b, tol: float = 1e-9) -> bool:
    if a[0] == "circle" and b[0] == "circle":
        return bool(np.linalg.norm(a[1] - b[1]) < a[2] + b[2] - tol)
    if a[0] == "circle":
        return _circle_polygon_share_area(a[1], a[2], b[1], tol)
    if b[0] == "circle":
        return _circle_polygon_share_area(b[1], b[2], a[1], tol)
    return _polys_share_area(a[1], b[1], tol)


def _allowed(item) -> bool:
    """Centre outside the middle 6 x 4 m, footprint inside the 10 x 8 m walls."""
    if abs(item.x) < 3.0 and abs(item.y) < 2.0:
        return False
    shape = _shape(item)
    if shape[0] == "circle":
        return abs(item.x) + DRUM_R <= 5.0 and abs(item.y) + DRUM_R <= 4.0
    poly = shape[1]
    return bool(np.all(np.abs(poly[:, 0]) <= 5.0 + 1e-12) and np.all(np.abs(poly[:, 1]) <= 4.0 + 1e-12))


def test_clutter_layout_obeys_the_papers_rules():
    seen_cabinet_over_pallet = 0
    for seed in range(25):
        raw = clutter.sample_clutter(ROOM, seed)
        kept = clutter.clutter_layout(ROOM, seed)
        candidates = [it for it in raw if _allowed(it)]
        assert set(kept) <= set(candidates)
        polys = {it.index: _shape(it) for it in candidates}
        for it in kept:
            assert 0.0 <= it.yaw < np.pi
            assert not (abs(it.x) < 3.0 and abs(it.y) < 2.0)
        for i, a in enumerate(kept):  # kept footprints never overlap
            for b in kept[i + 1 :]:
                assert not _share_area(polys[a.index], polys[b.index]), (seed, a, b)
        kept_ids = {it.index for it in kept}
        for it in candidates:
            if it.index in kept_ids:
                continue
            # a dropped item overlaps a kept one of higher or equal priority
            blockers = [k for k in kept if _share_area(polys[it.index], polys[k.index])]
            assert blockers and min(RANK[k.kind] for k in blockers) <= RANK[it.kind], (seed, it)
            if it.kind == "cabinet":  # ... and only cabinets remove cabinets
                assert any(k.kind == "cabinet" for k in blockers)
        # a raw pallet overlapping a kept cabinet never survives: the cabinet wins
        for cab in (k for k in kept if k.kind == "cabinet"):
            for pal in (c for c in candidates if c.kind == "pallet"):
                if _share_area(polys[cab.index], polys[pal.index]):
                    seen_cabinet_over_pallet += 1
                    assert pal.index not in kept_ids
        # greedy maximality within cabinets: a cabinet clear of earlier kept cabinets is kept
        for cab in (c for c in candidates if c.kind == "cabinet"):
            earlier = [k for k in kept if k.kind == "cabinet" and k.index < cab.index]
            if not any(_share_area(polys[cab.index], polys[k.index]) for k in earlier):
                assert cab.index in kept_ids
    assert seen_cabinet_over_pallet > 0  # the priority rule was exercised


def test_clutter_densities_follow_the_rates():
    seeds = range(1000)
    raw = {k: 0 for k in RATES}
    allowed = {k: 0 for k in RATES}
    for seed in seeds:
        for it in clutter.sample_clutter(ROOM, seed):
            raw[it.kind] += 1
            allowed[it.kind] += _allowed(it)
    yaw = np.linspace(0, np.pi, 2001)[:-1]
    for kind, rate in RATES.items():
        assert abs(raw[kind] / len(seeds) / (rate * 80.0) - 1) < 0.04, kind
        # centres may lie where the footprint clears the walls, outside the middle 6 x 4 m
        if kind == "drum":
            ex = ey = np.full_like(yaw, DRUM_R)
        else:
            w, d = SIZES[kind]
            ex = (w * np.abs(np.cos(yaw)) + d * np.abs(np.sin(yaw))) / 2
            ey = (w * np.abs(np.sin(yaw)) + d * np.abs(np.cos(yaw))) / 2
        area = np.mean((10 - 2 * ex) * (8 - 2 * ey)) - 24.0
        assert abs(allowed[kind] / len(seeds) / (rate * area) - 1) < 0.05, kind


def test_clutter_is_deterministic_in_the_seed(cell, plant):
    a, b = clutter.clutter_layout(ROOM, 42), clutter.clutter_layout(ROOM, 42)
    assert a == b and len(a) > 0
    assert clutter.clutter_layout(ROOM, 0) != clutter.clutter_layout(ROOM, 1)
    s1 = lab.build_scene(cell, plant, pcg_seed=0)
    s2 = lab.build_scene(cell, plant, pcg_seed=0)
    s3 = lab.build_scene(cell, plant, pcg_seed=1)

    def clutter_meshes(s):
        return [(m.name, m.vertices.tobytes()) for m in s.meshes if m.name.split("_")[0] in RATES]

    assert clutter_meshes(s1) == clutter_meshes(s2)
    assert clutter_meshes(s1) != clutter_meshes(s3)


def test_clutter_meshes_sit_on_their_footprints(cell, scene):
    room, items = clutter.lab_layout(cell, 42)
    meshes = {m.name: m for m in scene.meshes if m.name.split("_")[0] in RATES}
    assert sorted(meshes) == sorted(f"{it.kind}_{it.index:03d}" for it in items)
    assert {it.kind for it in items} == set(RATES)
    for it in items:
        v = meshes[f"{it.kind}_{it.index:03d}"].vertices
        assert abs(v[:, 2].min()) < 1e-9  # on the floor
        local = v[:, :2] - (it.x, it.y)
        c, s = np.cos(it.yaw), np.sin(it.yaw)
        local = local @ np.array([[c, -s], [s, c]])  # into the item's frame
        if it.kind == "drum":
            assert np.hypot(local[:, 0], local[:, 1]).max() <= DRUM_R + 1e-9
        else:
            w, d = SIZES[it.kind]
            np.testing.assert_allclose(local.min(axis=0), (-w / 2, -d / 2), atol=1e-9)
            np.testing.assert_allclose(local.max(axis=0), (w / 2, d / 2), atol=1e-9)
    # clutter keeps off the cell's furniture even when the cell reaches into the room
    wide = build_cell(CellConfig(arm_distance=3.0, stand_size=1.0))
    _, items = clutter.lab_layout(wide, 3)
    stands = [ob for ob in wide.obstacles if ob.name.endswith("_stand")]
    for it in items:
        for st in stands:
            h = np.asarray(st.size[:2]) / 2
            square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * h + st.world_T[:2, 3]
            assert not _share_area(_shape(it), ("poly", square))
