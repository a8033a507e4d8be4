"""The ``kinematic`` physics backend against truths computed independently of it.

Configurations are found with the core's own kinematics (a separate Pinocchio model per arm);
"in collision" is established analytically (a camera box whose every corner lies inside a box or
cylinder obstacle; two camera boxes a centimetre apart) or with an own ray-parity
point-in-mesh test on the URDF's collision STLs, so nothing here trusts coal or the backend.
"""

from __future__ import annotations

import re
import subprocess
import sys
from itertools import product

import numpy as np
import pytest

from agrisim.config import CellConfig
from agrisim.interfaces import JointTrajectory
from agrisim.plugins.physics.kinematic import KinematicOptions, agrisim_physics
from agrisim.plugins.physics.kinematic.backend import KinematicPhysics
from agrisim.plugins.rigs.paper.cell import build_cell
from agrisim.robot.cell import Box, Cylinder
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.urdf import CAMERA_BODY
from agrisim.scene.transforms import look_at, pose

RATE = 240.0


@pytest.fixture(scope="module")
def cell():
    return build_cell(CellConfig())


@pytest.fixture
def physics(cell):
    ph = KinematicPhysics(cell, KinematicOptions())
    yield ph
    ph.close()


@pytest.fixture(scope="module")
def kin(cell):
    return {arm.name: ArmKinematics(arm) for arm in cell.arms}


def home(cell, robot="r1"):
    return np.array(cell.arm(robot).home, float)


# ---------------------------------------------------------------- independent geometry


def camera_corners(kin: ArmKinematics, q: np.ndarray) -> np.ndarray:
    """World coordinates of the 8 corners of the camera collision box at ``q``."""
    T = kin.fk(q, "camera_link")
    half = np.array(CAMERA_BODY) / 2
    corners = np.array([s * half for s in product((-1, 1), repeat=3)])
    return corners @ T[:3, :3].T + T[:3, 3]


def inside_obstacle(ob, points: np.ndarray) -> np.ndarray:
    local = (points - ob.world_T[:3, 3]) @ ob.world_T[:3, :3]
    if isinstance(ob, Box):
        return np.all(np.abs(local) < np.array(ob.size) / 2, axis=1)
    assert isinstance(ob, Cylinder)
    return (np.hypot(local[:, 0], local[:, 1]) < ob.radius) & (np.abs(local[:, 2]) < ob.height / 2)


def load_stl(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of an STL (ASCII or binary), merged by exact coordinates."""
    data = open(path, "rb").read()
    if data[:5] == b"solid" and b"facet" in data[:300]:
        tri = np.array(re.findall(rb"vertex\s+(\S+)\s+(\S+)\s+(\S+)", data), float).reshape(-1, 3, 3)
    else:
        n = int(np.frombuffer(data, "<u4", 1, 80)[0])
        rec = np.frombuffer(data, np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), n, 84)
        tri = rec["v"].astype(float)
    verts, faces = np.unique(tri.reshape(-1, 3), axis=0, return_inverse=True)
    return verts, faces.reshape(-1, 3)


def points_inside_mesh(V: np.ndarray, F: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Ray-parity point-in-mesh test (Moller-Trumbore along one skew direction)."""
    d = np.array([0.5773, 0.5774, 0.5775])
    tri = V[F]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    h = np.cross(d, e2)
    a = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(a) > 1e-12
    f = np.where(ok, 1.0 / np.where(ok, a, 1.0), 0.0)
    s = P[:, None, :] - tri[None, :, 0]
    u = f * np.einsum("pij,ij->pi", s, h)
    qv = np.cross(s, e1[None])
    v = f * np.einsum("pij,j->pi", qv, d)
    t = f * np.einsum("pij,ij->pi", qv, e2)
    hits = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-12)
    return hits.sum(axis=1) % 2 == 1


def link_mesh_world(arm, kin: ArmKinematics, q: np.ndarray, link: str) -> tuple[np.ndarray, np.ndarray]:
    path = re.search(rf'<link name="{link}">.*?<collision>.*?filename="([^"]+)"', arm.urdf, re.S).group(1)
    V, F = load_stl(path)
    T = kin.link_poses(q)[link]
    return V @ T[:3, :3].T + T[:3, 3], F


def camera_down_at(p) -> np.ndarray:
    """A camera pose at ``p`` looking straight down (optical z = -world z)."""
    return pose(np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]), np.array(p, float))


def ik(kin: ArmKinematics, target: np.ndarray, q0: np.ndarray, restarts: int = 8) -> np.ndarray:
    res = kin.ik(target, q0, rng=np.random.default_rng(1), restarts=restarts)
    assert res.ok, res.reason
    return res.q


def self_pairs(labels: list[str], robot: str) -> list[str]:
    return [lab for lab in labels if all(side.startswith(f"{robot}/") for side in lab.split("|"))]


# ---------------------------------------------------------------- queries


def test_home_is_free_and_zero_has_no_self_collision(cell, physics):
    for arm in cell.arms:
        assert not physics.in_collision(arm.name, home(cell, arm.name))
    assert physics.collisions() == []
    for robot in cell.arm_names:
        # At zero the arm stretches into the plant's keep-out region; only its own links matter here.
        labels = physics.collisions(q={robot: np.zeros(6)})
        assert self_pairs(labels, robot) == []


@pytest.mark.parametrize(
    "obstacle, point",
    [("table", (0.15, 0.0, 0.74)), ("pot", (0.0, 0.0, 0.87)), ("plant_keepout", (0.05, 0.0, 1.05))],
)
def test_camera_driven_into_obstacle_collides(cell, physics, kin, obstacle, point):
    q = ik(kin["r1"], camera_down_at(point), home(cell))
    ob = next(o for o in cell.obstacles if o.name == obstacle)
    assert inside_obstacle(ob, camera_corners(kin["r1"], q)).all()  # the truth: fully inside
    assert physics.in_collision("r1", q)
    assert "|".join(sorted((obstacle, "r1/camera_link"))) in physics.collisions(q={"r1": q})
    assert not physics.in_collision("r1", home(cell))  # the query moved nothing


#: camera poses of r1 and r2 facing each other with their box centres 1 cm apart, above the
#: plant's keep-out, and a start next to one IK branch for each (elbows away from the other arm)
FACING = {
    "r1": look_at(np.array([-0.03, 0.4, 1.3]), np.array([-1.03, 0.4, 1.3])),
    "r2": look_at(np.array([0.03, 0.4, 1.3]), np.array([1.03, 0.4, 1.3])),
}
NEAR = {
    "r1": np.array([-0.59, -0.86, 1.07, -0.22, 0.98, -3.14]),
    "r2": np.array([-2.55, -2.29, -1.07, -2.92, -0.98, 3.14]),
}


def facing(kin) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """IK of FACING from NEAR, for r1 and r2: the same solution on every machine. From the arms'
    homes rounding decides (measured: r1's home moved by 1e-14 rad, 40 normal draws, ends on
    three solutions, 34/2/4; r2's moved by 1e-10 on two); from NEAR, on one for each arm with
    starts moved by up to 0.03 rad (40 draws each)."""
    q1 = ik(kin["r1"], FACING["r1"], NEAR["r1"], restarts=0)
    q2 = ik(kin["r2"], FACING["r2"], NEAR["r2"], restarts=0)
    assert np.max(np.abs(q1 - NEAR["r1"])) < 0.01 and np.max(np.abs(q2 - NEAR["r2"])) < 0.01
    return q1, q2


def test_arms_reaching_into_each_other_collide(cell, physics, kin):
    q1, q2 = facing(kin)
    clear = KinematicPhysics(cell, KinematicOptions(margin=0.03))  # alone, 3 cm from anything
    assert not clear.in_collision("r1", q1) and not clear.in_collision("r2", q2)
    c1, c2 = kin["r1"].fk(q1, "camera_link"), kin["r2"].fk(q2, "camera_link")
    assert np.linalg.norm(c1[:3, 3] - c2[:3, 3]) < 0.011  # boxes 5 x 4 x 4 cm: they overlap
    assert not physics.in_collision("r1", q1)  # alone (r2 at home) each is free
    assert not physics.in_collision("r2", q2)
    assert physics.in_collision("r1", q1, {"r2": q2})
    assert physics.in_collision("r2", q2, {"r1": q1})
    assert "r1/camera_link|r2/camera_link" in physics.collisions(q={"r1": q1, "r2": q2})
    assert physics.arms_in_collision({"r1": q1, "r2": q2})
    assert not physics.arms_in_collision({"r1": q1, "r2": home(cell, "r2")})
    # Deep in the table, but that is not the arms touching each other.
    q_table = ik(kin["r1"], camera_down_at((0.15, 0.0, 0.74)), home(cell))
    assert not physics.arms_in_collision({"r1": q_table, "r2": home(cell, "r2")})
    physics.reset("r2", q2)  # arms not named in `others` are where they are
    assert physics.in_collision("r1", q1)
    np.testing.assert_array_equal(physics.joint_positions("r2"), q2)


@pytest.mark.parametrize("margin", [0.0, 0.01])
def test_yes_no_queries_answer_as_a_test_of_every_pair(cell, margin):
    """``in_collision`` and ``arms_in_collision`` ask coal's AABB tree, which tests only the pairs
    whose bounds overlap; they must answer as Pinocchio's test of every active pair does, on
    random configurations of both arms (some colliding with the cell, some arm against arm,
    some only within the margin)."""
    import pinocchio as pin

    ph = KinematicPhysics(cell, KinematicOptions(margin=margin))
    rng = np.random.default_rng(7)
    r1, r2 = cell.arm_names
    every = {key: ph._geometry_data(frozenset(robots), between_only=between)[0]
             for key, robots, between in (("r1", (r1,), False), ("arms", (r1, r2), True))}  # fmt: skip
    outcomes = {"r1": [], "arms": []}
    for k in range(600):
        # about home (the cell and the arm itself) or about NEAR (the arms reaching into each other)
        centre, spread = (home, 0.9) if k % 2 else ((lambda _, name: NEAR[name]), 0.12)
        q = {name: centre(cell, name) + rng.normal(0.0, spread, 6) for name in (r1, r2)}
        full = ph._q.copy()
        for name in (r1, r2):
            full[ph._slices[name]] = q[name]
        truth = {
            key: bool(pin.computeCollisions(ph.model, ph.data, ph.geom, gdata, full, False))
            for key, gdata in every.items()
        }
        assert ph.in_collision(r1, q[r1], others={r2: q[r2]}) == truth["r1"], q
        assert ph.arms_in_collision(q) == truth["arms"], q
        assert bool(ph.collisions(frozenset((r1,)), q)) == truth["r1"], q
        for key in outcomes:
            outcomes[key].append(truth[key])
    for key, seen in outcomes.items():  # both answers drawn, or the comparison says little
        assert 0 < sum(seen) < len(seen), (key, sum(seen))
    ph.close()


def test_folded_elbow_self_collision(cell, physics, kin):
    arm = cell.arm("r1")
    folded = np.array([0.0, -np.pi / 2, 3.0, -np.pi / 2, -np.pi / 2, 0.0])  # forearm back on upper arm
    open_ = folded.copy()
    open_[2] = 2.6
    # Truth: wrist_1 mesh vertices inside the (watertight) upper-arm mesh.
    Va, Fa = link_mesh_world(arm, kin["r1"], folded, "upper_arm_link")
    Vb, _ = link_mesh_world(arm, kin["r1"], folded, "wrist_1_link")
    assert points_inside_mesh(Va, Fa, Vb).sum() > 10
    assert physics.in_collision("r1", folded)
    labels = physics.collisions(q={"r1": folded})
    assert "r1/upper_arm_link|r1/wrist_1_link" in labels
    assert labels == self_pairs(labels, "r1")  # up in the air: nothing but itself
    # The same pair less folded: truth says apart, and so does the backend.
    Va, Fa = link_mesh_world(arm, kin["r1"], open_, "upper_arm_link")
    Vb, _ = link_mesh_world(arm, kin["r1"], open_, "wrist_1_link")
    assert points_inside_mesh(Va, Fa, Vb).sum() == 0
    assert not physics.in_collision("r1", open_)


def test_adjacent_links_that_overlap_are_not_collisions(cell, physics, kin):
    # The UR10's neighbouring meshes interpenetrate by design at the joints (truth: vertices of
    # one inside the other at home); reporting them would make every configuration collide.
    arm = cell.arm("r1")
    Va, Fa = link_mesh_world(arm, kin["r1"], home(cell), "shoulder_link")
    Vb, _ = link_mesh_world(arm, kin["r1"], home(cell), "upper_arm_link")
    assert points_inside_mesh(Va, Fa, Vb).any()
    assert not physics.in_collision("r1", home(cell))


def test_queries_are_history_independent(cell, physics):
    # (Their rate is measured by bench/robot_episode.py, not asserted: machines differ.)
    rng = np.random.default_rng(0)
    Q = rng.uniform(-np.pi, np.pi, (1500, 6))
    forward = [physics.in_collision("r1", q) for q in Q]
    backward = [physics.in_collision("r1", q) for q in Q[::-1]][::-1]
    assert forward == backward
    assert 0.1 < np.mean(forward) < 0.9  # random joints: both answers occur


def test_unknown_arm_and_bad_shape_are_errors(physics):
    with pytest.raises(KeyError, match="r9"):
        physics.in_collision("r9", np.zeros(6))
    with pytest.raises(KeyError, match="r9"):
        physics.in_collision("r1", np.zeros(6), {"r9": np.zeros(6)})
    with pytest.raises(ValueError, match="6 joints"):
        physics.reset("r1", np.zeros(5))


# ---------------------------------------------------------------- execution


def smooth_plan(qa: np.ndarray, qb: np.ndarray, duration: float, rate: float = RATE) -> JointTrajectory:
    n = int(np.ceil(duration * rate))
    t = np.minimum(np.arange(n + 1) / rate, duration)
    s = (1 - np.cos(np.pi * t / duration)) / 2
    q = qa + s[:, None] * (qb - qa)
    qd = (np.pi / (2 * duration)) * np.sin(np.pi * t / duration)[:, None] * (qb - qa)
    return JointTrajectory(t, q, qd)


def test_perfect_tracking_equals_plan(cell, physics):
    qa = home(cell, "r1")
    qb = qa + np.array([0.3, -0.2, 0.25, 0.1, -0.3, 0.5])
    plan = smooth_plan(qa, qb, 1.5)
    short = smooth_plan(home(cell, "r2"), home(cell, "r2") + 0.1, 0.5)
    t0 = physics.sim_time
    seen = []

    def settled(robot, q):
        seen.append((robot, q.copy()))
        return True

    out = physics.execute({"r1": plan, "r2": short}, settled, timeout=5.0)
    ex = out["r1"].executed
    np.testing.assert_array_equal(ex.q, plan.q)
    np.testing.assert_allclose(ex.t, plan.t + t0, atol=1e-12)
    np.testing.assert_allclose(ex.qd, plan.qd, atol=1e-12)
    assert physics.sim_time == pytest.approx(t0 + 1.5)  # the longest plan
    np.testing.assert_array_equal(physics.joint_positions("r1"), qb)
    np.testing.assert_array_equal(physics.joint_positions("r2"), short.q[-1])
    assert {r for r, _ in seen} == {"r1", "r2"}
    np.testing.assert_array_equal(dict(seen)["r1"], qb)
    for r in ("r1", "r2"):
        assert out[r].settled and out[r].settle_time == 0.0 and out[r].contacts == []


def test_unsettled_reports_timeout_and_other_rates(cell):
    ph = KinematicPhysics(cell, KinematicOptions(rate=120.0))
    qa = home(cell)
    plan = smooth_plan(qa, qa + 0.2, 1.0)
    out = ph.execute({"r1": plan}, lambda r, q: False, timeout=5.0)["r1"]
    assert not out.settled and out.settle_time == 5.0
    assert ph.sim_time == pytest.approx(1.0)  # perfect tracking never gets closer: no waiting
    np.testing.assert_allclose(out.executed.q, plan.q[::2], atol=1e-12)  # every other 240 Hz sample
    np.testing.assert_allclose(out.executed.t, plan.t[::2], atol=1e-12)


def test_contacts_reported_for_trajectory_through_table(cell, physics, kin):
    q_table = ik(kin["r1"], camera_down_at((0.15, 0.0, 0.74)), home(cell))
    qa = home(cell)
    there = smooth_plan(qa, q_table, 1.0)
    back = smooth_plan(q_table, qa, 1.0)
    plan = JointTrajectory(np.concatenate([there.t, back.t[1:] + 1.0]), np.vstack([there.q, back.q[1:]]))
    still = smooth_plan(home(cell, "r2"), home(cell, "r2"), 0.2)
    out = physics.execute({"r1": plan, "r2": still}, lambda r, q: True, 5.0)
    contacts = out["r1"].contacts
    assert "r1/camera_link|table" in contacts
    assert contacts == sorted(set(contacts))
    assert all("|" in c and "r1/" in c for c in contacts)
    assert out["r2"].contacts == []  # r2 held still at home, far from everything
    # It ends back home, free, and the reported contacts are exactly what the samples collide with.
    assert not physics.in_collision("r1", physics.joint_positions("r1"))
    truth = set()
    for q in plan.q:
        truth.update(physics.collisions(frozenset({"r1"}), {"r1": q}))
    assert set(contacts) == truth


def test_contacts_between_arms_moving_together(cell, physics, kin):
    q1, q2 = facing(kin)  # (not IK from the homes: which branch it ends on is rounding's choice)
    # Each goal is free on its own (see above); r2 arrives half a second after r1 and only then
    # do the cameras meet, so this is found only by checking both arms at the same instants.
    out = physics.execute(
        {"r1": smooth_plan(home(cell, "r1"), q1, 1.0), "r2": smooth_plan(home(cell, "r2"), q2, 1.5)},
        lambda r, q: True,
        5.0,
    )
    assert "r1/camera_link|r2/camera_link" in out["r1"].contacts
    assert "r1/camera_link|r2/camera_link" in out["r2"].contacts


# ---------------------------------------------------------------- registration


def test_registration_and_options():
    (spec,) = agrisim_physics()
    assert spec.name == "kinematic" and spec.factory.resolve() is KinematicPhysics
    assert spec.options_model is KinematicOptions and spec.description and spec.limits
    assert KinematicOptions().rate == 240.0
    with pytest.raises(ValueError):
        KinematicOptions(rate=0)
    with pytest.raises(ValueError):
        KinematicOptions(bogus=1)


def test_registered_through_entry_point(monkeypatch):
    from agrisim.registry import Registry, make_plugin_manager

    monkeypatch.setenv("AGRISIM_LOAD_PLUGINS", "physics-kinematic")
    spec = Registry(make_plugin_manager(autoload=True)).get("physics", "kinematic")
    assert spec.factory.resolve() is KinematicPhysics


def test_module_does_not_import_pybullet():
    code = "import sys, agrisim.plugins.physics.kinematic.backend; sys.exit('pybullet' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
