"""The kinematic physics backend: Pinocchio kinematics and coal collision checks (see the package)."""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from agrisim.interfaces import Execution, JointTrajectory, PhysicsBackend
from agrisim.plugins.physics.kinematic import KinematicOptions
from agrisim.robot.cell import Box, Cell, Cylinder, Obstacle


@dataclass(frozen=True)
class _Geom:
    """What the backend needs to know about one collision geometry."""

    label: str  # "r1/forearm_link" or an obstacle's name, as reported in contacts
    owner: str | None  # arm name, None for a cell obstacle
    joint: int  # Pinocchio joint carrying it (0 = fixed in the world)


def _prefixed_urdf(urdf: str, prefix: str) -> str:
    """The URDF with every link and joint name prefixed, so several arms fit in one model."""
    root = ET.fromstring(urdf)
    for el in root.iter():
        if el.tag in ("link", "joint") and "name" in el.attrib:
            el.set("name", prefix + el.attrib["name"])
        elif el.tag in ("parent", "child") and "link" in el.attrib:
            el.set("link", prefix + el.attrib["link"])
        elif el.tag == "mimic" and "joint" in el.attrib:
            el.set("joint", prefix + el.attrib["joint"])
    return ET.tostring(root, encoding="unicode")


def _obstacle_geometry(ob: Obstacle) -> coal.CollisionGeometry:
    if isinstance(ob, Box):
        return coal.Box(*map(float, ob.size))  # full extents, as coal wants them
    if isinstance(ob, Cylinder):
        return coal.Cylinder(float(ob.radius), float(ob.height))  # centred, z-aligned: as the cell's
    raise TypeError(f"unsupported obstacle type {type(ob).__name__} ({ob.name!r})")


def _robust(request: coal.CollisionRequest) -> None:
    """Make a pair's collision request reliable and independent of earlier queries.

    Pinocchio's defaults (GJK warm-started from the previous query's guess, early-stopping GJK
    without contact) miss deep overlaps: coal 3.0.x reports two nearly aligned boxes overlapping by
    4 cm as separated once the guess comes from an earlier query. Full GJK + EPA from the default
    guess costs nothing for separated pairs (most of them) and makes ``in_collision`` a pure
    function of the configuration, as planners assume.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the flag is deprecated but still read
        request.enable_cached_gjk_guess = False
    request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
    request.enable_contact = True
    request.num_max_contacts = 1


class KinematicPhysics(PhysicsBackend):
    """Arms that track their plans exactly; collisions from Pinocchio + coal.

    Built from a :class:`agrisim.robot.cell.Cell`; arms start at their ``home`` configuration.
    """

    def __init__(self, cell: Cell, options: KinematicOptions | None = None) -> None:
        options = options if options is not None else KinematicOptions()
        super().__init__(cell, options)
        model, geom = pin.Model(), pin.GeometryModel()
        self._slices: dict[str, slice] = {}
        for arm in cell.arms:
            urdf = _prefixed_urdf(arm.urdf, f"{arm.name}/")
            arm_model = pin.buildModelFromXML(urdf)
            missing = [j for j in arm.joints if not arm_model.existJointName(f"{arm.name}/{j}")]
            if missing or arm_model.nq != len(arm.joints):
                raise ValueError(f"arm {arm.name!r}: URDF joints do not match {arm.joints} (missing {missing})")
            arm_geom = pin.buildGeomFromUrdfString(arm_model, urdf, pin.GeometryType.COLLISION)
            first_q = model.nq
            base = pin.SE3(np.asarray(arm.world_T_base, float))
            model, geom = pin.appendModel(model, arm_model, geom, arm_geom, 0, base)
            # appendModel keeps the URDF's joint order; read it back rather than assume it.
            idx = [model.idx_qs[model.getJointId(f"{arm.name}/{j}")] for j in arm.joints]
            if idx != list(range(first_q, first_q + len(arm.joints))):
                raise ValueError(f"arm {arm.name!r}: joints {arm.joints} are not in the URDF's tree order")
            self._slices[arm.name] = slice(first_q, first_q + len(arm.joints))
        n_arm_geoms = geom.ngeoms
        for ob in cell.obstacles:
            placement = pin.SE3(np.asarray(ob.world_T, float))
            geom.addGeometryObject(pin.GeometryObject(ob.name, 0, 0, placement, _obstacle_geometry(ob)))
        self.model, self.geom = model, geom
        self.data = model.createData()
        self._geoms = self._describe_geometries(n_arm_geoms)
        for a, b in self._collision_pairs():
            geom.addCollisionPair(pin.CollisionPair(a, b))
        # The GeometryModel keeps its pairs in its own order: index results by that order.
        self._pairs = [(cp.first, cp.second) for cp in geom.collisionPairs]
        self._labels = ["|".join(sorted((self._geoms[a].label, self._geoms[b].label))) for a, b in self._pairs]
        self._involves = {
            name: np.array([name in (self._geoms[a].owner, self._geoms[b].owner) for a, b in self._pairs])
            for name in self._slices
        }
        self._gdata: dict[tuple[frozenset[str], bool], tuple[pin.GeometryData, list[int]]] = {}
        self._broadphase: dict[tuple[frozenset[str], bool], Any] = {}
        self._q = np.zeros(model.nq)
        for arm in cell.arms:
            self._q[self._slices[arm.name]] = arm.home
        self._time = 0.0

    # ------------------------------------------------------------------ set-up
    def _describe_geometries(self, n_arm_geoms: int) -> list[_Geom]:
        out = []
        for i, obj in enumerate(self.geom.geometryObjects):
            if i >= n_arm_geoms:  # the cell's obstacles were added after every arm
                out.append(_Geom(obj.name, None, 0))
                continue
            frame = self.model.frames[obj.parentFrame].name  # "r1/forearm_link": the link, not "_0"
            owner = frame.split("/", 1)[0]
            out.append(_Geom(frame, owner, obj.parentJoint))
        return out

    def _adjacent(self, a: _Geom, b: _Geom) -> bool:
        """One rigid body, or bodies joined by one joint (they touch by design)."""
        parents = self.model.parents
        return a.joint == b.joint or parents[a.joint] == b.joint or parents[b.joint] == a.joint

    def _collision_pairs(self) -> list[tuple[int, int]]:
        stands = {arm.name: arm.stand for arm in self.cell.arms}
        pairs = []
        for i, a in enumerate(self._geoms):
            for j in range(i + 1, len(self._geoms)):
                b = self._geoms[j]
                if a.owner is None and b.owner is None:
                    continue  # the cell never moves
                if a.owner is None or b.owner is None:
                    arm_geom, ob = (b, a) if a.owner is None else (a, b)
                    # The base rests on its stand; geometries fixed to the world are the base.
                    if arm_geom.joint == 0 and ob.label == stands[arm_geom.owner]:
                        continue
                elif a.owner == b.owner and self._adjacent(a, b):
                    continue
                pairs.append((i, j))
        return pairs

    def _geometry_data(
        self, robots: frozenset[str], *, between_only: bool = False
    ) -> tuple[pin.GeometryData, list[int]]:
        """Geometry data with exactly the pairs involving ``robots`` active, and their indices (cached).

        ``between_only`` keeps only pairs of two different arms, both among ``robots``.
        """
        key = (robots, between_only)
        cached = self._gdata.get(key)
        if cached is None:
            gdata = pin.GeometryData(self.geom)
            active = np.zeros(len(self._pairs), bool)
            for r in robots:
                active |= self._involves[r]
            if between_only:
                owners = [(self._geoms[i].owner, self._geoms[j].owner) for i, j in self._pairs]
                active &= np.array([a in robots and b in robots and a != b for a, b in owners])
            for k, on in enumerate(active):
                if not on:
                    gdata.deactivateCollisionPair(k)
                _robust(gdata.collisionRequests[k])
                a, b = (self._geoms[i] for i in self._pairs[k])
                if self.options.margin > 0 and a.owner != b.owner:
                    gdata.collisionRequests[k].security_margin = self.options.margin
            cached = self._gdata[key] = (gdata, [int(k) for k in np.flatnonzero(active)])
        return cached

    def _any_collision(self, robots: frozenset[str], full: np.ndarray, *, between_only: bool = False) -> bool:
        """Does any pair involving ``robots`` collide at ``full``? A yes/no query (the planner's,
        thousands a plan) through coal's dynamic AABB tree, which tests only pairs whose bounds
        overlap (margins included): the same answers as every active pair's test
        (tests/unit/test_physics_kinematic.py), 2-3x faster in the paper's cell."""
        key = (robots, between_only)
        manager = self._broadphase.get(key)
        if manager is None:
            gdata, _ = self._geometry_data(robots, between_only=between_only)
            manager = self._broadphase[key] = pin.BroadPhaseManager_DynamicAABBTreeCollisionManager(
                self.model, self.geom, gdata
            )
        return bool(pin.computeCollisions(self.model, self.data, manager, full, True))

    def _check(self, robot: str) -> None:
        if robot not in self._slices:
            raise KeyError(f"no arm named {robot!r}; arms are {list(self._slices)}")

    def _as_q(self, robot: str, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, float).reshape(-1)
        n = self._slices[robot].stop - self._slices[robot].start
        if q.shape != (n,):
            raise ValueError(f"arm {robot!r} has {n} joints, got q of shape {q.shape}")
        return q

    # ------------------------------------------------------------------ queries
    def in_collision(self, robot: str, q: np.ndarray, others: Mapping[str, np.ndarray] | None = None) -> bool:
        """Is ``robot`` at ``q`` in collision with itself, the cell, or the other arms?

        ``others`` gives other arms' configurations; arms not named stay where they are.
        """
        self._check(robot)
        full = self._q.copy()
        full[self._slices[robot]] = self._as_q(robot, q)
        for name, q_other in (others or {}).items():
            if name != robot:  # the queried q wins over a stale entry for the robot itself
                self._check(name)
                full[self._slices[name]] = self._as_q(name, q_other)
        return self._any_collision(frozenset((robot,)), full)

    def arms_in_collision(self, configs: Mapping[str, np.ndarray]) -> bool:
        """Do the arms at ``configs`` touch each other? Only arm-against-arm pairs are tested."""
        full = self._q.copy()
        for name, q in configs.items():
            self._check(name)
            full[self._slices[name]] = self._as_q(name, q)
        if len(configs) < 2:
            return False
        return self._any_collision(frozenset(configs), full, between_only=True)

    def collisions(self, robots: frozenset[str] | None = None, q: Mapping[str, np.ndarray] | None = None) -> list[str]:
        """All colliding pairs ``"a|b"`` involving ``robots`` (default: every arm), sorted.

        ``q`` overrides arms' configurations; the others stay where they are.
        """
        robots = frozenset(self._slices) if robots is None else frozenset(robots)
        for name in robots:
            self._check(name)
        full = self._q.copy()
        for name, qn in (q or {}).items():
            self._check(name)
            full[self._slices[name]] = self._as_q(name, qn)
        if not self._any_collision(robots, full):
            return []
        return self._colliding(*self._geometry_data(robots), full)

    def self_distance(self, robot: str, q: np.ndarray) -> float:
        """The least distance, m, between ``robot``'s own links that no joint joins, at ``q``
        (coal's exact meshes; 0 where two touch)."""
        self._check(robot)
        full = self._q.copy()
        full[self._slices[robot]] = self._as_q(robot, q)
        gdata, active = self._geometry_data(frozenset((robot,)))
        own = [k for k in active if self._geoms[self._pairs[k][0]].owner == self._geoms[self._pairs[k][1]].owner]
        pin.computeDistances(self.model, self.data, self.geom, gdata, full)
        return min((max(gdata.distanceResults[k].min_distance, 0.0) for k in own), default=np.inf)

    def _colliding(self, gdata: pin.GeometryData, active: list[int], full: np.ndarray) -> list[str]:
        if not pin.computeCollisions(self.model, self.data, self.geom, gdata, full, False):
            return []
        results = gdata.collisionResults
        return sorted({self._labels[k] for k in active if results[k].isCollision()})

    def joint_positions(self, robot: str) -> np.ndarray:
        """The arm's current joint positions."""
        self._check(robot)
        return self._q[self._slices[robot]].copy()

    def reset(self, robot: str, q: np.ndarray) -> None:
        """Place the arm at ``q`` (no simulated motion, no time passes)."""
        self._check(robot)
        self._q[self._slices[robot]] = self._as_q(robot, q)

    @property
    def sim_time(self) -> float:
        """Simulated seconds since the backend was built."""
        return self._time

    def link_poses(self, robot: str) -> dict[str, np.ndarray]:
        """``world_T_link`` of every link of ``robot`` (URDF link frames) at its current joints."""
        self._check(robot)
        pin.framesForwardKinematics(self.model, self.data, self._q)
        prefix = f"{robot}/"
        return {
            f.name[len(prefix) :]: self.data.oMf[i].homogeneous.copy()
            for i, f in enumerate(self.model.frames)
            if f.type == pin.FrameType.BODY and f.name.startswith(prefix)
        }

    # ------------------------------------------------------------------ motion
    # The fixed-step loop of all arms moving together, with settling and contacts; one loop, one state.
    def execute(
        self,
        plans: Mapping[str, JointTrajectory],
        settled: Callable[[str, np.ndarray], bool],
        timeout: float,
    ) -> dict[str, Execution]:
        """Play the plans together; each arm is exactly where its plan says, sampled at ``rate``.

        Simulated time advances by the longest plan. An arm whose final position fails
        ``settled`` would never get closer (tracking is perfect), so it is reported unsettled
        with ``settle_time = timeout`` without simulating the wait. ``executed.t`` is in
        simulated time. Contacts of every arm are checked at every sample against the cell, itself
        and the other arms at their simultaneous positions.
        """
        if not plans:
            return {}
        dt = 1.0 / self.options.rate
        for r, plan in plans.items():
            self._check(r)
            if len(plan.t) == 0 or plan.q.shape != (len(plan.t), self._slices[r].stop - self._slices[r].start):
                raise ValueError(f"plan for {r!r}: q has shape {plan.q.shape} for {len(plan.t)} times")
        durations = {r: p.duration for r, p in plans.items()}
        horizon = max(durations.values())
        t0 = self._time

        def grid(duration: float) -> np.ndarray:
            # Same construction as TimedPath.discretize: every 1/rate, the end point included.
            n = max(int(np.ceil(duration / dt - 1e-9)), 0)
            return np.minimum(np.arange(n + 1) * dt, duration)

        def snapped(plan: JointTrajectory, t: np.ndarray) -> np.ndarray:
            # k * (1/rate) and k / rate can differ in the last bit: land on the plan's own sample
            # times where they coincide, so that equal rates reproduce the plan exactly.
            rel = plan.t - plan.t[0]
            hi = np.clip(np.searchsorted(rel, t), 0, len(rel) - 1)
            lo = np.maximum(hi - 1, 0)
            near = np.where(np.abs(rel[lo] - t) < np.abs(rel[hi] - t), lo, hi)
            return np.where(np.abs(rel[near] - t) <= 1e-9, rel[near], t)

        def at(plan: JointTrajectory, t: np.ndarray, values: np.ndarray) -> np.ndarray:
            rel = plan.t - plan.t[0]
            return np.column_stack([np.interp(t, rel, values[:, j]) for j in range(values.shape[1])])

        executed: dict[str, JointTrajectory] = {}
        for r, plan in plans.items():
            t = snapped(plan, grid(durations[r]))
            q = at(plan, t, plan.q)
            if plan.qd is not None:
                qd = at(plan, t, plan.qd)
            elif len(t) > 1:
                qd = np.gradient(q, t, axis=0)
            else:
                qd = np.zeros_like(q)
            executed[r] = JointTrajectory(t + t0, q, qd)

        contacts: dict[str, set[str]] = {r: set() for r in plans}
        if self.options.check_contacts:
            moving = frozenset(plans)
            gdata, active = self._geometry_data(moving)
            t_all = grid(horizon)
            # Past its end an arm holds its last sample: np.interp clamps there.
            tracks = {r: at(plans[r], t_all, plans[r].q) for r in plans}
            full = self._q.copy()
            for k in range(len(t_all)):
                for r in plans:
                    full[self._slices[r]] = tracks[r][k]
                if not self._any_collision(moving, full):  # the usual answer, and the quick one
                    continue
                for label in self._colliding(gdata, active, full):
                    for r in plans:
                        if any(side.startswith(f"{r}/") for side in label.split("|")):
                            contacts[r].add(label)

        for r, plan in plans.items():
            self._q[self._slices[r]] = plan.q[-1]
        self._time = t0 + horizon
        out = {}
        for r, plan in plans.items():
            ok = bool(settled(r, plan.q[-1].copy()))
            out[r] = Execution(
                executed=executed[r],
                settled=ok,
                settle_time=0.0 if ok else float(timeout),
                contacts=sorted(contacts[r]),
            )
        return out
