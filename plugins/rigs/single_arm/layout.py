"""Where the one arm goes, sized by what it reaches: its workspace sampled with Pinocchio's
forward kinematics, the cell laid out from it, and a home that is within limits and free of
collisions (checked by the kinematic backend's Pinocchio + coal model of the cell)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from agrisim.errors import UserError
from agrisim.robot.cell import Arm, Cell
from agrisim.robot.kinematics import ArmKinematics
from agrisim.scene.transforms import look_at

#: random configurations whose camera positions measure the arm's reach
REACH_SAMPLES = 3000
#: a first guess puts the hemisphere's farthest viewpoint this share of the reach from the
#: shoulder: the wrist must still turn the camera onto the plant there
FAR = 0.8
#: viewpoints farther than this share of the reach are refused as unreachable
REFUSE = 0.95
#: the default hemisphere radius, a share of the camera's reach (the paper's UR10: about 0.5 m)...
RADIUS_SHARE = 0.35
#: ...within these bounds, m
RADIUS_BOUNDS = (0.12, 0.6)
#: the arm's base keeps at least this much more than the radius from the plant centre, m
BASE_CLEARANCE = 0.1
#: distances and radii tried, as shares of the first guess's, best first
DISTANCE_SCALES = (1.0, 0.9, 1.1, 0.8, 1.2, 0.7)
RADIUS_SCALES = (1.0, 0.8, 0.65)
#: the hemisphere's extreme viewpoints a layout is tried on: polar angles (the routine's
#: range) and azimuths across the arm's half, degrees
PROBE_POLAR = (36.0, 540.0 / 7.0)
PROBE_AZIMUTH = (180.0 / 19.0 - 90.0, 0.0, 90.0 - 180.0 / 19.0)  # the routine's default theta range, turned
#: random configurations a home is looked for among when IK finds none
HOME_SAMPLES = 400
#: the polar angles (from the zenith) of the viewpoints a computed home looks from, degrees
HOME_POLAR_DEG = (36.0, 60.0)
#: how far a computed home keeps from every obstacle, m: pybullet refuses to plan from a start
#: within its clearance (5 mm by default), which the kinematic backend's exact test would pass
HOME_MARGIN = 0.01
#: ...and its own links at least as far apart as at its zero joints, less this, m: pybullet's
#: convex hulls of a UR5's forearm and wrist came within its clearance at a home whose exact
#: meshes were 10 mm apart (15 mm at zero joints)
HOME_SELF_SLACK = 0.002


@dataclass(frozen=True)
class Reach:
    """What an arm reaches: its shoulder (the second arm joint's origin) in the base frame, and
    the farthest its camera frame gets from there, m."""

    shoulder: np.ndarray
    radius: float


def measure_reach(kin: ArmKinematics, samples: int = REACH_SAMPLES) -> Reach:
    """The arm's :class:`Reach`, from ``samples`` configurations drawn uniformly within its
    joint limits (seeded: the same arm gives the same answer). ``kin`` has its base at the origin."""
    import pinocchio as pin

    model, data = kin.model, kin.data
    pin.forwardKinematics(model, data, np.clip(np.zeros(kin.dof), kin.lower, kin.upper))
    shoulder = data.oMi[min(2, model.njoints - 1)].translation.copy()
    rng = np.random.default_rng(0)
    far = 0.0
    for q in rng.uniform(kin.lower, kin.upper, (samples, kin.dof)):
        pin.framesForwardKinematics(model, data, q)
        far = max(far, float(np.linalg.norm(data.oMf[kin.tip].translation - shoulder)))
    return Reach(shoulder, far)


def _first_distance(reach: Reach, radius: float, above: float) -> float:
    """The distance that puts the hemisphere's rim beside the arm :data:`FAR` of the reach from
    the shoulder (``above`` the plant centre), at least :data:`BASE_CLEARANCE` beyond the rim."""
    squared = (FAR * reach.radius) ** 2 - radius**2 - above**2
    return max(math.sqrt(max(squared, 0.0)), radius + BASE_CLEARANCE)


def _reached(cell: Cell, radius: float, aim: float) -> int:
    """How many of the probe viewpoints IK reaches free of collisions in ``cell``."""
    from agrisim.plugins.physics.kinematic.backend import KinematicPhysics

    arm = cell.arms[0]
    kin, physics = ArmKinematics(arm), KinematicPhysics(cell)
    rng = np.random.default_rng(0)
    centre = cell.plant_center
    count = 0
    for polar in np.radians(PROBE_POLAR):
        for azimuth in np.radians(PROBE_AZIMUTH):
            direction = np.array(
                [math.sin(polar) * math.cos(azimuth), math.sin(polar) * math.sin(azimuth), math.cos(polar)]
            )
            target = look_at(centre + radius * direction, centre + np.array([0.0, 0.0, aim]))
            # from anywhere, as a run's IK comes from wherever the last view left the arm: a
            # layout whose low viewpoints only the zero joints' basin reaches (a Panda's) fails
            found = kin.ik(
                target,
                rng.uniform(kin.lower, kin.upper),
                is_valid=lambda q: not physics.in_collision(arm.name, q),
                rng=rng,
                restarts=4,
                max_restarts=16,
            )
            count += found.ok
    return count


def choose_layout(
    make_cell: Callable[[float, float, float], Cell],
    reach: Reach,
    radius: float | None,
    stands: Sequence[float],
    above: Callable[[float], float],
    aim: float,
    robot: str,
) -> tuple[float, float, float]:
    """(distance, radius, stand height) for a run that gives no distance: on each of ``stands``
    in turn (the shoulder ``above(stand)`` the plant centre), from a first guess by the reach
    (:func:`_first_distance`, :data:`RADIUS_SHARE`), the first of a few scaled layouts
    (``make_cell(distance, radius, stand)``) whose extreme viewpoints IK reaches free of
    collisions (else the one reaching most); ``radius`` given, only distances are tried. A lower
    stand lets a long hand (the Panda's, with its camera) reach the hemisphere's low ring, whose
    cameras look at the plant from beside the pot. Refused when the best reaches fewer than half."""
    if radius is None:
        r0 = float(np.clip(RADIUS_SHARE * reach.radius, *RADIUS_BOUNDS))
        radii = [r0 * s for s in RADIUS_SCALES]
    else:
        radii = [radius]
    best = (-1, 0.0, 0.0, 0.0)
    total = len(PROBE_POLAR) * len(PROBE_AZIMUTH)
    for stand in stands:
        for r in radii:
            d0 = _first_distance(reach, r, above(stand))
            for scale in DISTANCE_SCALES:
                d = max(d0 * scale, r + BASE_CLEARANCE)
                n = _reached(make_cell(d, r, stand), r, aim)
                if n > best[0]:
                    best = (n, d, r, stand)
                if n == total:
                    return d, r, stand
    if best[0] * 2 < total:
        raise UserError(
            f"rig single-arm: {robot} (camera reach about {reach.radius:.2f} m) reaches {best[0]} of {total} test "
            f"viewpoints around the plant at best; "
            # (the Z1 reaches 0.95 m, but its wrist's limits, +-87 and +-77 degrees, turn its camera
            # onto the plant from few viewpoints: not only size decides)
            + (
                "try another rig.single-arm.radius or another robot"
                if radius is not None
                else "its size or its joints' limits keep the plant out of its camera's view; choose another robot"
            )
        )
    return best[1], best[2], best[3]


def check_reach(shoulder_world: np.ndarray, reach: Reach, eyes: Sequence[np.ndarray], robot: str) -> None:
    """Refuse viewpoints farther from the shoulder than the arm reaches (:data:`REFUSE`)."""
    worst = max((float(np.linalg.norm(np.asarray(e) - shoulder_world)) for e in eyes), default=0.0)
    if worst > REFUSE * reach.radius:
        raise UserError(
            f"rig single-arm: {robot} reaches about {reach.radius:.2f} m from its shoulder but a viewpoint is "
            f"{worst:.2f} m away; lower rig.single-arm.distance or rig.single-arm.radius"
        )


def home_pose(cell: Cell, arm: Arm, kin: ArmKinematics, radius: float, aim: float) -> np.ndarray:
    """A collision-free configuration within limits, :data:`HOME_MARGIN` clear of everything:
    the camera on the hemisphere's side facing the arm, looking at the plant (where the routine
    starts, so the first move is short)."""
    from agrisim.plugins.physics.kinematic import KinematicOptions
    from agrisim.plugins.physics.kinematic.backend import KinematicPhysics

    physics = KinematicPhysics(cell, KinematicOptions.model_validate({"margin": HOME_MARGIN}))
    centre = cell.plant_center
    towards = arm.world_T_base[:3, 3] - centre
    towards[2] = 0.0
    towards /= max(float(np.linalg.norm(towards)), 1e-9)
    start = np.clip(np.zeros(kin.dof), kin.lower, kin.upper)
    apart = physics.self_distance(arm.name, start) - HOME_SELF_SLACK

    def clear(q: np.ndarray) -> bool:
        return not physics.in_collision(arm.name, q) and physics.self_distance(arm.name, q) >= apart

    for polar in np.radians(HOME_POLAR_DEG):
        eye = centre + radius * (math.sin(polar) * towards + np.array([0.0, 0.0, math.cos(polar)]))
        target = look_at(eye, centre + np.array([0.0, 0.0, aim]))
        found = kin.ik(
            target,
            start,
            is_valid=clear,
            rng=np.random.default_rng(0),
            max_restarts=200,
        )
        if found.q is not None:
            return found.q
    # no viewpoint of the routine's side has a free branch near the stand: any free
    # configuration with the camera above the table, nearest the zero one, is a start
    rng = np.random.default_rng(0)
    table = float(cell.plant_center[2])
    free = [
        q
        for q in rng.uniform(kin.lower, kin.upper, (HOME_SAMPLES, kin.dof))
        if kin.fk(q)[2, 3] > table + 0.1 and clear(q)
    ]
    if free:
        return min(free, key=lambda q: float(np.linalg.norm(q)))
    raise UserError(
        f"rig single-arm: no collision-free home found for arm {arm.name!r} ({found.reason}); "
        "give one as rig.single-arm.home"
    )


def check_home(cell: Cell, arm: Arm, kin: ArmKinematics, home: Sequence[float]) -> None:
    """Refuse a user's home that does not fit the arm, leaves its limits, or collides."""
    from agrisim.plugins.physics.kinematic.backend import KinematicPhysics

    q = np.asarray(home, float)
    if q.shape != (kin.dof,):
        raise UserError(f"rig.single-arm.home: the arm has {kin.dof} joints {list(arm.joints)}, got {len(q)} values")
    outside = [n for n, v, lo, hi in zip(arm.joints, q, kin.lower, kin.upper, strict=True) if not lo <= v <= hi]
    if outside:
        raise UserError(f"rig.single-arm.home: joints {outside} are outside their limits")
    hits = KinematicPhysics(cell).collisions(q={arm.name: q})
    if hits:
        raise UserError(f"rig.single-arm.home is in collision: {', '.join(hits)}")
