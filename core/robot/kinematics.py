"""Forward and inverse kinematics of one arm, on Pinocchio.

IK is damped least squares on the SE(3) log error of the camera frame, with joint limits and
restarts from random seeds. Among the converged solutions, the caller's validity test (collision
with the cell and the other arm) filters and the one nearest the current joints wins, so arms
do not swing through half a turn to reach a neighbouring setpoint.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from agrisim.robot.cell import Arm

#: damped least squares: J J^T + this (6 x 6) is never singular
_DAMPING = 1e-6 * np.eye(6)
#: numpy.linalg.solve's own kernel for one right-hand side (LAPACK gesv), without its checks
_solve6 = np.linalg._umath_linalg.solve1


def _norm3(v: np.ndarray) -> float:
    """Euclidean norm as numpy.linalg.norm computes it for a float vector: sqrt(v . v)."""
    return math.sqrt(v.dot(v))


@dataclass
class IkResult:
    """An IK answer: ``q`` (None when nothing acceptable was found) and why."""

    q: np.ndarray | None
    position_error: float  # m
    rotation_error: float  # rad
    attempts: int
    reason: str = ""
    #: other acceptable solutions, nearest first (for when ``q`` cannot be planned to)
    alternatives: list[np.ndarray] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.q is not None


class ArmKinematics:
    """Pinocchio model of one arm (its base placed in the world)."""

    def __init__(self, arm: Arm) -> None:
        self.arm = arm
        full = pin.buildModelFromXML(arm.urdf)
        # Joints outside the arm's list (none for the UR10) would be locked at zero.
        keep = [full.getJointId(j) for j in arm.joints]
        lock = [j for j in range(1, full.njoints) if j not in keep]
        self.model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
        self.data = self.model.createData()
        self.world_T_base = np.asarray(arm.world_T_base, float)
        self._base = pin.SE3(self.world_T_base)
        self.tip = self.model.getFrameId(arm.camera_frame)
        if self.tip >= self.model.nframes:
            raise ValueError(f"frame {arm.camera_frame!r} not in the URDF")
        self.lower = np.array(self.model.lowerPositionLimit, float)
        self.upper = np.array(self.model.upperPositionLimit, float)
        self.velocity_limit = np.array(self.model.velocityLimit, float)
        self.dof = self.model.nq
        #: (frame id, link name) of the URDF's links: link_poses runs for every sample of
        #: every move the recording shows
        self._links = [(fid, f.name) for fid, f in enumerate(self.model.frames) if f.type == pin.FrameType.BODY]

    # ------------------------------------------------------------------ forward
    def fk(self, q: np.ndarray, frame: str | None = None) -> np.ndarray:
        """``world_T_frame`` (default: the camera optical frame) at joints ``q``."""
        fid = self.tip if frame is None else self.model.getFrameId(frame)
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, float))
        return (self._base * self.data.oMf[fid]).homogeneous

    def link_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """``world_T_link`` of every body frame (links of the URDF) at ``q``."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, float))
        base, oMf = self._base, self.data.oMf
        return {name: (base * oMf[fid]).homogeneous for fid, name in self._links}

    # ------------------------------------------------------------------ inverse
    def _solve(self, target: pin.SE3, q0: np.ndarray, iterations: int, tol: float) -> tuple[np.ndarray, float, float]:
        # Tens of thousands of iterations per run, each a few microseconds of arithmetic: numpy's
        # wrappers (norm, solve, eye, clip) cost more than their work, so the loop calls what
        # they call (the same float operations: the same answers, bit for bit).
        model, data, tip = self.model, self.data, self.tip
        lower, upper = self.lower, self.upper
        fk, log6, jlog6, jacobian, local = (
            pin.framesForwardKinematics,
            pin.log6,
            pin.Jlog6,
            pin.computeFrameJacobian,
            pin.ReferenceFrame.LOCAL,
        )
        oMf = data.oMf
        q = q0.copy()
        # A step is a function of q alone, so a q seen before starts a cycle that never
        # converges (it would have): the q the loop would end on is known without running on.
        # Seeds that fail mostly end so (stuck on a joint limit, or swapping between a few
        # configurations): half of their iterations, skipped with the same answer bit for bit.
        seen: dict[bytes, int] = {}
        visited: list[np.ndarray] = []
        for step in range(iterations):
            first = seen.setdefault(q.tobytes(), step)
            if first != step:
                q = visited[first + (iterations - first) % (step - first)]
                break
            visited.append(q)
            fk(model, data, q)
            current_T_target = oMf[tip].actInv(target)
            err = log6(current_T_target).vector
            if _norm3(err[:3]) < tol and _norm3(err[3:]) < tol:
                break
            J = jlog6(current_T_target) @ jacobian(model, data, q, tip, local).reshape(6, -1)  # (6,) for one joint
            dq = J.T @ _solve6(J @ J.T + _DAMPING, err)
            q = np.minimum(np.maximum(q + dq, lower), upper)
        pin.framesForwardKinematics(model, data, q)
        err = pin.log6(data.oMf[tip].actInv(target)).vector
        return q, _norm3(err[:3]), _norm3(err[3:])

    def solve(
        self, world_T_target: np.ndarray, q0: np.ndarray, iterations: int = 200, tol: float = 5e-8
    ) -> tuple[np.ndarray, float, float]:
        """One run of :meth:`ik`'s damped least-squares loop from ``q0``, without restarts or
        checks: (joints, position error in m, rotation error in rad) at ``world_T_target``."""
        target = self._base.actInv(pin.SE3(np.asarray(world_T_target, float)))
        return self._solve(target, np.asarray(q0, float), iterations, tol)

    def nearest_equivalent(self, q: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Shift joints by whole turns towards ``reference``, staying within limits."""
        out = q.copy()
        for i in range(self.dof):
            turns = np.round((reference[i] - q[i]) / (2 * np.pi))
            for k in (turns, turns - np.sign(turns)) if turns else (0,):
                cand = q[i] + 2 * np.pi * k
                if self.lower[i] <= cand <= self.upper[i]:
                    out[i] = cand
                    break
        return out

    def ik(
        self,
        world_T_target: np.ndarray,
        q_current: np.ndarray,
        *,
        is_valid: Callable[[np.ndarray], bool] | None = None,
        rng: np.random.Generator,
        restarts: int = 8,
        max_restarts: int = 100,
        iterations: int = 200,
        position_tolerance: float = 5e-5,
        rotation_tolerance: float = 1e-4,
    ) -> IkResult:
        """Joints putting the camera frame at ``world_T_target``, nearest ``q_current``.

        Tries the current joints first, then ``restarts`` random seeds (half near the current
        joints, half anywhere); keeps solutions within
        the tolerances that ``is_valid`` accepts; returns the one nearest ``q_current``. While no
        acceptable solution is found it keeps trying, up to ``max_restarts`` seeds: near the
        arm's base most IK branches fold the arm into its stand, and the free ones are rare.
        """
        target = self._base.actInv(pin.SE3(np.asarray(world_T_target, float)))
        q_current = np.asarray(q_current, float)
        # Converge far below the acceptance tolerance: the physics has to track it too.
        tol = min(position_tolerance, rotation_tolerance) * 1e-3
        seed_span = np.minimum(np.abs(self.lower), np.pi), np.minimum(self.upper, np.pi)
        found: list[tuple[float, np.ndarray, float, float]] = []
        closest_err = (np.inf, np.inf)
        rejected = 0
        attempts = 0
        first_found = -1
        for attempt in range(max(restarts, max_restarts) + 1):
            # Enough: `restarts` seeds tried, and as many again since the first solution
            # (a hard target gets the same chance to show alternatives as an easy one).
            if found and attempt > restarts and attempt > first_found + restarts:
                break
            attempts += 1
            if attempt == 0:
                q0 = q_current
            elif attempt <= restarts // 2:
                # Seeds around the current joints, spreading wider each time, find the
                # branches next to the one the arm is on (a wrist flip, say).
                spread = 0.3 + 1.7 * attempt / max(restarts // 2, 1)
                q0 = np.clip(q_current + rng.normal(0.0, spread, self.dof), self.lower, self.upper)
            else:
                q0 = rng.uniform(-seed_span[0], seed_span[1])
            q, ep, er = self._solve(target, q0, iterations, tol)
            if ep > position_tolerance or er > rotation_tolerance:
                closest_err = min(closest_err, (ep, er))
                continue
            q = self.nearest_equivalent(q, q_current)
            if any(np.allclose(q, f[1], atol=1e-3) for f in found):
                continue  # the same branch again
            if is_valid is not None and not is_valid(q):
                rejected += 1
                continue
            dist = float(np.linalg.norm(q - q_current))
            found.append((dist, q, ep, er))
            if first_found < 0:
                first_found = attempt
            if attempt == 0 and dist < 0.5:  # a warm start that stayed close is the answer
                break
        if not found:
            if rejected:
                reason = f"ik: all {rejected} solutions found are in collision"
            else:
                reason = f"ik: no solution within tolerance (closest {closest_err[0] * 1e3:.3f} mm, {closest_err[1]:.2e} rad)"
            return IkResult(None, closest_err[0], closest_err[1], attempts, reason)
        found.sort(key=lambda f: f[0])
        dist, q, ep, er = found[0]
        return IkResult(q, ep, er, attempts, alternatives=[f[1] for f in found[1:]])
