"""The pybullet physics backend: the world, its bodies and motors, and trajectory execution (see the package)."""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from agrisim.interfaces import Execution, JointTrajectory, PhysicsBackend
from agrisim.plugins.native_output import native_output_silenced
from agrisim.plugins.physics.pybullet_physics import BulletOptions
from agrisim.robot.cell import Box, Cell, Cylinder
from agrisim.scene.transforms import quat_xyzw

with native_output_silenced():  # pybullet prints its build time on import
    import pybullet as pb
    from pybullet_utils.bullet_client import BulletClient

#: an arm whose joints all move slower than this, rad/s, has come to rest
REST_SPEED = 1e-4
#: at most one trim of an arm's hold command in this long, s (the arm must answer the last)
TRIM_INTERVAL = 0.25


def _without_visuals(urdf: str) -> str:
    """The URDF without its ``<visual>`` elements: the worlds here only simulate and test
    collisions (inertia comes from the file, bounds from the collision shapes), and pybullet
    spends a third of a second per arm reading the UR10's visual meshes."""
    root = ElementTree.fromstring(urdf)
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    return ElementTree.tostring(root, encoding="unicode")


class _Client(BulletClient):
    """A BulletClient that binds each pybullet function to its server once. The base class
    builds a new ``functools.partial`` (after an ``inspect`` test) on every attribute access,
    and a run's collision queries and simulation steps make some 400,000 of them."""

    def __getattr__(self, name: str) -> object:
        attribute = super().__getattr__(name)
        if name != "disconnect":  # the base class marks the client closed when it is looked up
            setattr(self, name, attribute)  # ordinary lookup finds it from now on
        return attribute


class _World:
    """One pybullet world holding the cell: arms, obstacles, collision filters."""

    # Builds the simulated world in order (arms, stands, table, pot, collision filters); each
    # step depends on the previous ones.
    def __init__(
        self,
        cell: Cell,
        urdf_dir: Path,
        *,
        dynamics: bool,
        gravity: float = 9.81,
        dt: float = 1 / 240,
        margin: float = 0.0,
    ) -> None:
        with native_output_silenced():
            self.client = _Client(connection_mode=pb.DIRECT)
        c = self.client
        self.margin = margin
        if dynamics:
            c.setGravity(0, 0, -gravity)
            c.setTimeStep(dt)
        self.bodies: dict[str, int] = {}  # obstacle name -> body id
        self.names: dict[int, str] = {}
        for ob in cell.obstacles:
            if isinstance(ob, Box):
                shape = c.createCollisionShape(pb.GEOM_BOX, halfExtents=[s / 2 for s in ob.size])
            elif isinstance(ob, Cylinder):
                shape = c.createCollisionShape(pb.GEOM_CYLINDER, radius=ob.radius, height=ob.height)
            else:  # pragma: no cover - Cell only holds these two
                raise TypeError(f"unsupported obstacle {ob!r}")
            body = c.createMultiBody(
                baseMass=0,
                baseCollisionShapeIndex=shape,
                basePosition=ob.world_T[:3, 3].tolist(),
                baseOrientation=quat_xyzw(ob.world_T[:3, :3]),
            )
            self.bodies[ob.name] = body
            self.names[body] = ob.name
        self.ignored: set[tuple[int, int, int, int]] = set()  # (body, link, other, link) pairs
        self.shaped: dict[str, list[int]] = {}  # arm -> links with collision shapes
        self.shaped_by_body: dict[int, list[int]] = {body: [-1] for body in self.bodies.values()}
        self._box_cache: dict[int, np.ndarray] = {}  # bounds, dropped when a body moves
        self.arms: dict[str, int] = {}
        self.self_pairs: dict[str, list[tuple[int, int]]] = {}
        self._self_index: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # self_pairs as rows of bounds
        self._others_cache: dict[
            tuple[str, str | None], tuple[list[tuple[int, list[int]]], np.ndarray, np.ndarray]
        ] = {}
        self.joints: dict[str, list[int]] = {}
        self.links: dict[str, dict[int, str]] = {}
        flags = pb.URDF_USE_SELF_COLLISION | pb.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT | pb.URDF_USE_INERTIA_FROM_FILE
        for arm in cell.arms:
            urdf = urdf_dir / f"{arm.name}.urdf"
            if not urdf.exists():
                urdf.write_text(_without_visuals(arm.urdf))
            with native_output_silenced():  # the URDF importer warns on stdout
                body = c.loadURDF(
                    str(urdf),
                    basePosition=arm.world_T_base[:3, 3].tolist(),
                    baseOrientation=quat_xyzw(arm.world_T_base[:3, :3]),
                    useFixedBase=True,
                    flags=flags,
                )
            self.arms[arm.name] = body
            self.names[body] = arm.name
            by_name = {}
            links = {-1: c.getBodyInfo(body)[0].decode()}
            parent: dict[int, int] = {}
            fixed: set[int] = set()
            for j in range(c.getNumJoints(body)):
                info = c.getJointInfo(body, j)
                by_name[info[1].decode()] = j
                links[j] = info[12].decode()
                parent[j] = info[16]
                if info[2] == pb.JOINT_FIXED:
                    fixed.add(j)
            self.joints[arm.name] = [by_name[n] for n in arm.joints]
            self.links[arm.name] = links

            # Links welded by fixed joints form one rigid part (flange, ee_link, camera): each
            # link's part is named by its first ancestor behind a moving joint. Parts touching
            # themselves or their parent part is not a collision, nor the base part its stand.
            def part(j: int, fixed: set[int] = fixed, parent: dict[int, int] = parent) -> int:
                while j in fixed:
                    j = parent[j]
                return j

            def part_parent(p: int, parent: dict[int, int] = parent) -> int:
                return part(parent[p]) if p >= 0 else -2

            shaped = [j for j in links if c.getCollisionShapeData(body, j)]
            pairs = []
            for i, a in enumerate(shaped):
                for b in shaped[i + 1 :]:
                    pa, pb_ = part(a), part(b)
                    if pa == pb_ or part_parent(pa) == pb_ or part_parent(pb_) == pa:
                        c.setCollisionFilterPair(body, body, a, b, 0)
                    else:
                        pairs.append((a, b))
            self.self_pairs[arm.name] = pairs
            index = {j: i for i, j in enumerate(shaped)}  # link -> row of its bounds
            self._self_index[arm.name] = (
                np.array([index[a] for a, _ in pairs], np.intp),
                np.array([index[b] for _, b in pairs], np.intp),
            )
            self.shaped[arm.name] = shaped
            self.shaped_by_body[body] = shaped
            stand = self.bodies[arm.stand]
            for j in shaped:
                if part(j) == -1:
                    c.setCollisionFilterPair(body, stand, j, -1, 0)
                    self.ignored.add((body, j, stand, -1))
            for j in range(c.getNumJoints(body)):
                # pybullet turns on velocity motors by default, which act as joint friction
                c.setJointMotorControl2(body, j, pb.VELOCITY_CONTROL, force=0)

    def set_joints(self, robot: str, q: np.ndarray) -> None:
        body, idx = self.arms[robot], self.joints[robot]
        self._box_cache.pop(body, None)
        self.client.resetJointStatesMultiDof(body, idx, [[float(x)] for x in q], targetVelocities=[[0.0]] * len(idx))

    def _boxes(self, body: int, links: list[int]) -> np.ndarray:
        """Axis-aligned bounds of ``links`` of ``body``, (n, 2, 3)."""
        if body not in self._box_cache:
            self._box_cache[body] = np.array([self.client.getAABB(body, j) for j in links])
        return self._box_cache[body]

    def _others(self, robot: str, only: str | None) -> tuple[list[tuple[int, list[int]]], np.ndarray, np.ndarray]:
        """The bodies ``near`` checks ``robot`` against, with their shaped links, and for each
        row of their stacked bounds its body (position in that list) and its link's position."""
        key = (robot, only)
        if key not in self._others_cache:
            body = self.arms[robot]
            others = (
                [(o, ol) for o, ol in self.shaped_by_body.items() if o != body]
                if only is None
                else [(self.arms[only], self.shaped[only])]
            )
            owner = np.repeat(np.arange(len(others)), [len(ol) for _, ol in others])
            column = np.concatenate([np.arange(len(ol)) for _, ol in others])
            self._others_cache[key] = (others, owner, column)
        return self._others_cache[key]

    def near(self, robot: str, only: str | None = None) -> list[str]:
        """The first pair involving ``robot`` closer than ``margin`` (empty when clear);
        ``only`` restricts the search to that other arm.

        pybullet's contact detection only sees penetration, so clearance is asked pair by pair
        with closest-point queries, for the pairs whose bounds (grown by the margin) overlap.
        """
        c, body, m = self.client, self.arms[robot], self.margin
        links = self.shaped[robot]
        mine = self._boxes(body, links)
        lo, hi = mine[:, 0] - m, mine[:, 1] + m
        # All other links' bounds at once (one numpy pass, not one per body: this runs for every
        # collision check of IK, planning and execution); candidates in the order a loop over
        # bodies, my links, their links would give them, so the first pair found is the same.
        others, owner, column = self._others(robot, only)
        theirs = np.concatenate([self._boxes(o, ol) for o, ol in others])
        overlap = ((lo[:, None] <= theirs[None, :, 1]) & (hi[:, None] >= theirs[None, :, 0])).all(axis=2)
        ii, kk = np.nonzero(overlap)
        candidates: list[tuple[int, int, int]] = []  # (other body, my link, its link)
        for n in np.lexsort((kk, ii, owner[kk])).tolist():
            other, olinks = others[owner[kk[n]]]
            a, b = links[ii[n]], olinks[column[kk[n]]]
            if (body, a, other, b) not in self.ignored:
                candidates.append((other, a, b))
        if only is None and self.self_pairs[robot]:
            ia, ib = self._self_index[robot]
            close = ((lo[ia] <= mine[ib, 1]) & (hi[ia] >= mine[ib, 0])).all(axis=1)
            candidates += [(body, *self.self_pairs[robot][n]) for n in np.flatnonzero(close).tolist()]
        for other, a, b in candidates:
            for cp in c.getClosestPoints(body, other, m, linkIndexA=a, linkIndexB=b):
                if cp[8] <= m:
                    return [self._pair(robot, cp)]
        return []

    def _pair(self, robot: str, cp: tuple) -> str:
        a = f"{robot}/{self.links[robot][cp[3]]}"
        name = self.names.get(cp[2], str(cp[2]))
        b = f"{name}/{self.links[name][cp[4]]}" if name in self.links else name
        return "|".join(sorted((a, b)))

    def contacts(self, robot: str) -> list[str]:
        """Penetrating pairs involving ``robot`` found by the last collision detection."""
        body = self.arms[robot]
        # near misses are reported too: only distance <= 0 is a contact
        return [self._pair(robot, cp) for cp in self.client.getContactPoints(bodyA=body) if cp[8] <= 0.0]

    def close(self) -> None:
        try:
            self.client.disconnect()
        except pb.error:
            pass


class BulletPhysics(PhysicsBackend):
    """The cell in pybullet: position-controlled arms with dynamics, plus a query world."""

    def __init__(self, cell: Cell, options: BulletOptions) -> None:
        super().__init__(cell, options)
        self._tmp = tempfile.TemporaryDirectory(prefix="agrisim-pybullet-")
        self.dt = 1.0 / options.rate
        urdf_dir = Path(self._tmp.name)
        self.sim = _World(cell, urdf_dir, dynamics=True, gravity=options.gravity, dt=self.dt)
        self.query = _World(cell, urdf_dir, dynamics=False, margin=options.clearance)
        self._q: dict[str, np.ndarray] = {a.name: np.array(a.home, float) for a in cell.arms}
        self._query_q: dict[str, np.ndarray] = {}
        self._time = 0.0
        c = self.sim.client
        self._force: dict[str, list[float]] = {}
        for arm in cell.arms:
            body = self.sim.arms[arm.name]
            self._force[arm.name] = [
                c.getJointInfo(body, j)[10] * options.force_scale for j in self.sim.joints[arm.name]
            ]
            self.reset(arm.name, self._q[arm.name])

    # ------------------------------------------------------------------ queries
    def _place_query(self, robot: str, q: np.ndarray) -> None:
        last = self._query_q.get(robot)
        if last is None or not np.array_equal(last, q):
            self.query.set_joints(robot, q)
            self._query_q[robot] = np.array(q, float)

    def in_collision(self, robot: str, q: np.ndarray, others: Mapping[str, np.ndarray] | None = None) -> bool:
        others = others or {}
        for name in self._q:
            self._place_query(name, q if name == robot else others.get(name, self._q[name]))
        if self.query.margin > 0:
            return bool(self.query.near(robot))
        self.query.client.performCollisionDetection()
        return bool(self.query.contacts(robot))

    def arms_in_collision(self, configs: Mapping[str, np.ndarray]) -> bool:
        for name, q in configs.items():
            self._place_query(name, q)
        names = list(configs)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                if self.query.near(a, only=b):
                    return True
        return False

    def joint_positions(self, robot: str) -> np.ndarray:
        return self._q[robot].copy()

    def reset(self, robot: str, q: np.ndarray) -> None:
        q = np.asarray(q, float)
        self.sim.set_joints(robot, q)
        self._q[robot] = q.copy()
        self._command(robot, q, np.zeros_like(q))

    @property
    def sim_time(self) -> float:
        return self._time

    # ------------------------------------------------------------------ dynamics
    def _command(self, robot: str, q: np.ndarray, qd: np.ndarray) -> None:
        o = self.options
        n = len(q)
        self.sim.client.setJointMotorControlArray(
            self.sim.arms[robot],
            self.sim.joints[robot],
            pb.POSITION_CONTROL,
            targetPositions=q.tolist(),
            targetVelocities=qd.tolist(),
            forces=self._force[robot],
            positionGains=[o.position_gain] * n,
            velocityGains=[o.velocity_gain] * n,
        )

    def _read(self, robot: str) -> np.ndarray:
        states = self.sim.client.getJointStates(self.sim.arms[robot], self.sim.joints[robot])
        return np.array([s[0] for s in states])

    def _commands(self, plan: JointTrajectory, end: float) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions and velocities (steps x joints) of ``plan`` at the simulation's
        steps ``step * dt`` up to ``end``."""
        n = int(end / self.dt) + 2
        t = np.arange(n) * self.dt  # step * dt, as the loop computes it
        t = t[t <= end]
        q = np.column_stack([np.interp(t, plan.t, plan.q[:, j]) for j in range(plan.q.shape[1])])
        if plan.qd is None:
            return q, np.zeros_like(q)
        return q, np.column_stack([np.interp(t, plan.t, plan.qd[:, j]) for j in range(plan.qd.shape[1])])

    def execute(
        self,
        plans: Mapping[str, JointTrajectory],
        settled: Callable[[str, np.ndarray], bool],
        timeout: float,
    ) -> dict[str, Execution]:
        robots = list(plans)
        ends = {r: plans[r].t[-1] for r in robots}
        done: dict[str, float] = {}  # robot -> settle time after its plan ended
        times: dict[str, list[float]] = {r: [] for r in robots}
        samples: dict[str, list[np.ndarray]] = {r: [] for r in robots}
        contacts: dict[str, set[str]] = {r: set() for r in robots}
        t0 = self._time
        step = 0
        horizon = max(ends.values()) + timeout
        # The commanded joints at every step of each plan, interpolated up front: one np.interp
        # per joint over all steps instead of one per joint and step (the same values).
        commands = {r: self._commands(plans[r], ends[r]) for r in robots}
        # what each arm is told to hold once its plan has ended: its last waypoint, trimmed by
        # the error it rests at (position motors under gravity stop short of their target; a
        # Panda's wrist by 0.06 mm at the camera, past the reach tolerance)
        holds = {r: plans[r].q[-1].copy() for r in robots}
        trimmed = {r: -np.inf for r in robots}
        last = {r: self._q[r].copy() for r in robots}
        while len(done) < len(robots):
            t = step * self.dt
            for r in robots:
                if r in done:
                    continue
                qs, qds = commands[r]
                if step < len(qs):
                    q, qd = qs[step], qds[step]
                else:
                    q, qd = holds[r], np.zeros(plans[r].q.shape[1])
                self._command(r, q, qd)
            self.sim.client.stepSimulation()
            step += 1
            self._time = t0 + step * self.dt
            t = step * self.dt
            for r in robots:
                if r in done:
                    continue
                q = self._read(r)
                self._q[r] = q
                times[r].append(self._time)
                samples[r].append(q)
                contacts[r].update(self.sim.contacts(r))
                if t >= ends[r] and settled(r, q):
                    done[r] = t - ends[r]
                elif t >= ends[r] + timeout:
                    done[r] = -1.0
                elif (
                    t >= ends[r]
                    and t - trimmed[r] >= TRIM_INTERVAL
                    and np.abs(q - last[r]).max() < REST_SPEED * self.dt
                ):
                    holds[r] = holds[r] + (plans[r].q[-1] - q)
                    trimmed[r] = t
                last[r] = q
            if t > horizon:
                break
        out = {}
        for r in robots:
            settle = done.get(r, -1.0)
            out[r] = Execution(
                executed=JointTrajectory(np.array(times[r]), np.array(samples[r])),
                settled=settle >= 0.0,
                settle_time=settle if settle >= 0.0 else timeout,
                contacts=sorted(contacts[r]),
            )
        return out

    def link_poses(self, robot: str) -> dict[str, np.ndarray]:
        """``world_T_link`` of every link as pybullet has them (URDF link frames)."""
        c, body = self.sim.client, self.sim.arms[robot]
        out = {}
        for j, name in self.sim.links[robot].items():
            if j < 0:
                pos, orn = c.getBasePositionAndOrientation(body)
            else:
                st = c.getLinkState(body, j, computeForwardKinematics=True)
                pos, orn = st[4], st[5]
            T = np.eye(4)
            T[:3, :3] = np.array(c.getMatrixFromQuaternion(orn)).reshape(3, 3)
            T[:3, 3] = pos
            out[name] = T
        return out

    def close(self) -> None:
        self.sim.close()
        self.query.close()
        self._tmp.cleanup()
