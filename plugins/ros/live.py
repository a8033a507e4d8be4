"""A live session of the cell: the episode's backends opened and driven by commands from outside
(joint trajectories, take-a-view triggers) instead of by the routine alone, paced to the wall
clock so that a middleware can publish the arms as they move.

Transport-free: the ROS bridges (``agrisim.plugins.ros``) turn messages into calls of
:meth:`LiveSession.submit` and publish what :attr:`LiveSession.motion` and the
``agrisim_capture`` hook report. Every backend runs on the thread that calls
:meth:`LiveSession.serve` (PyBullet and the renderers are not thread-safe); other threads
queue work and wait for its result. Every move and view goes into the run directory as a run's
do, so ``recon``, the exports and the recording work on a live session's output.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import pluggy

from agrisim.config import RunConfig
from agrisim.episode import TRAJECTORY_RATE, Episode
from agrisim.errors import UserError
from agrisim.interfaces import Capture, Execution, JointTrajectory, PhysicsBackend, Trajectory
from agrisim.records import Run, RunSummary, SetpointResult
from agrisim.robot.segments import segment_is_valid
from agrisim.robot.setpoints import Setpoint

T = TypeVar("T")


class Refused(UserError):
    """A command the session will not carry out; its message says why and what is allowed. The
    session goes on. ``kind``: what was wrong, for middlewares with codes of their own
    (``joints``: the joint names; ``goal``: anything else)."""

    def __init__(self, message: str, kind: str = "goal") -> None:
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class MoveResult:
    """What became of one commanded trajectory."""

    robot: str
    frame: str  # the setpoint it is saved as (``trajectories/<frame>.json``)
    reached: bool
    duration_s: float  # simulated seconds, trajectory and settling
    contacts: list[str]
    reason: str


class ArmMotion:
    """Where the arms are on the wall clock, for publishers on other threads: the physics'
    executed samples replayed at ``real_time_factor`` (seconds of simulation per wall second)."""

    def __init__(self, home: Mapping[str, np.ndarray], real_time_factor: float) -> None:
        self.real_time_factor = real_time_factor
        self._lock = threading.Lock()
        self._rest = {r: (np.asarray(q, float), np.zeros(len(q))) for r, q in home.items()}
        self._playing: dict[str, tuple[float, JointTrajectory]] = {}

    def play(self, executed: Mapping[str, JointTrajectory]) -> float:
        """Start replaying these executed trajectories now; returns the wall time they end."""
        now = time.monotonic()
        rtf = self.real_time_factor
        with self._lock:
            for robot, jt in executed.items():
                if len(jt.t):
                    self._rest[robot] = (np.asarray(jt.q[-1], float), np.zeros(jt.q.shape[1]))
                    if rtf > 0:
                        self._playing[robot] = (now, jt)
        longest = max((jt.duration for jt in executed.values()), default=0.0)
        return now + (longest / rtf if rtf > 0 else 0.0)

    def state(self, now: float | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Every arm's joint positions and velocities at wall time ``now`` (monotonic clock)."""
        now = time.monotonic() if now is None else now
        out = {}
        with self._lock:
            for robot, rest in self._rest.items():
                playing = self._playing.get(robot)
                if playing is None:
                    out[robot] = rest
                    continue
                start, jt = playing
                t = jt.t[0] + (now - start) * self.real_time_factor
                if t >= jt.t[-1]:
                    del self._playing[robot]
                    out[robot] = rest
                    continue
                q = np.array([np.interp(t, jt.t, jt.q[:, j]) for j in range(jt.q.shape[1])])
                qd = (
                    np.array([np.interp(t, jt.t, jt.qd[:, j]) for j in range(jt.qd.shape[1])])
                    if jt.qd is not None
                    else np.full(len(q), np.nan)
                )
                out[robot] = (q, qd)
        return out


class PacedPhysics:
    """The chosen physics backend, with every execution replayed on the wall clock: the call
    returns when the replay ends, so the next command starts where a watcher saw the arm stop."""

    def __init__(self, inner: PhysicsBackend, motion: ArmMotion) -> None:
        self._inner, self._motion = inner, motion

    def execute(
        self,
        plans: Mapping[str, JointTrajectory],
        settled: Callable[[str, np.ndarray], bool],
        timeout: float,
    ) -> dict[str, Execution]:
        executions = self._inner.execute(plans, settled, timeout)
        end = self._motion.play({r: ex.executed for r, ex in executions.items()})
        time.sleep(max(0.0, end - time.monotonic()))
        return executions

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


class LiveSession(Episode):
    """The cell, loaded as ``agrisim run`` loads it, served to commands.

    ``routine``: the paper's setpoints are run by :meth:`run_routine` (the paper's automatic
    mode); otherwise the session only moves when told to. Usage: ``open()``, then ``serve()``
    on one thread while others ``submit(...)``, then ``close(status)``.
    """

    def __init__(
        self,
        config: RunConfig,
        *,
        routine: bool = False,
        real_time_factor: float = 1.0,
        pm: pluggy.PluginManager | None = None,
    ) -> None:
        if not (real_time_factor >= 0 and math.isfinite(real_time_factor)):
            raise UserError(f"real time factor {real_time_factor!r}: must be 0 (unpaced) or a positive number")
        super().__init__(config, pm)
        if not routine:
            self.setpoints = {arm.name: [] for arm in self.cell.arms}
        self.routine_running = False
        self.motion = ArmMotion({a.name: np.asarray(a.home, float) for a in self.cell.arms}, real_time_factor)
        self._queue: queue.Queue[tuple[Callable[[], Any], Future[Any]]] = queue.Queue()
        self._stop = threading.Event()
        #: the setpoint a view taken now belongs to, per arm: the last move's, until it is captured
        self._uncaptured: dict[str, Setpoint | None] = {a.name: None for a in self.cell.arms}
        self._summary: RunSummary | None = None

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> Run:
        run = super().open()
        self._physics = PacedPhysics(self._physics, self.motion)  # type: ignore[assignment]
        return run

    def submit(self, work: Callable[[], T]) -> Future[T]:
        """Queue ``work`` for the serving thread; its result (or exception) comes in the future."""
        future: Future[T] = Future()
        if self._stop.is_set():
            future.set_exception(Refused("the session is shutting down"))
        else:
            self._queue.put((work, future))
        return future

    def serve(self, until: Callable[[], bool] = lambda: False) -> None:
        """Run queued work on this thread until :meth:`stop` or ``until()`` (checked every 0.1 s)."""
        while not (self._stop.is_set() or until()):
            self.drain(timeout=0.1)

    def drain(self, timeout: float = 0.0) -> None:
        """Run the queued work (waiting up to ``timeout`` for the first)."""
        while True:
            try:
                work, future = self._queue.get(timeout=timeout) if timeout else self._queue.get_nowait()
            except queue.Empty:
                return
            timeout = 0.0
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(work())
            except BaseException as exc:  # the caller's to report; Ctrl-C still stops the session
                future.set_exception(exc)
                if isinstance(exc, KeyboardInterrupt):
                    raise

    def stop(self) -> None:
        """Make :meth:`serve` return; later submissions are refused."""
        self._stop.set()

    def close(self, status: str, error: str = "") -> RunSummary:
        """As :meth:`Episode.close`; a second call returns the first one's summary."""
        if self._summary is not None:
            return self._summary
        self._stop.set()
        while True:  # whoever still waits hears why nothing happens
            try:
                _, future = self._queue.get_nowait()
            except queue.Empty:
                break
            if future.set_running_or_notify_cancel():
                future.set_exception(Refused("the session is shutting down"))
        self._summary = super().close(status, error)
        return self._summary

    def run_routine(self, progress: Callable[[int, int], None] | None = None) -> None:
        """The paper's setpoints, in order, answering queued triggers between them; trajectories
        sent meanwhile are refused."""
        steps = max((len(s) for s in self.setpoints.values()), default=0)
        self.routine_running = True
        try:
            for k in range(steps):
                if self._stop.is_set():
                    return
                self.step(k)
                self.drain()
                if progress:
                    progress(k + 1, steps)
        finally:
            self.routine_running = False

    # ------------------------------------------------------------------ commands (serving thread)
    def joint_names(self, robot: str) -> list[str]:
        return list(self.cell.arm(robot).joints)

    def execute(
        self,
        robot: str,
        names: Sequence[str],
        times: Sequence[float],
        positions: Sequence[Sequence[float]],
        velocities: Sequence[Sequence[float]] | None = None,
    ) -> MoveResult:
        """Carry out one joint trajectory (``times`` from its start, seconds; ``positions`` one
        row per time in ``names``' order), as a trajectory controller would: checked against the
        joint position and velocity limits and for collisions along the way first, refused
        whole if any check fails."""
        if self.routine_running:
            raise Refused(f"{robot}: the routine is running; trajectories are taken when it has finished")
        self._check_arm(robot)
        t, q, qd = self._checked_trajectory(robot, names, times, positions, velocities)
        q_now = np.asarray(self._physics.joint_positions(robot), float)
        if t[0] > 0:  # a trajectory starting later starts from where the arm is
            t, q = np.concatenate([[0.0], t]), np.vstack([q_now, q])
            qd = np.vstack([np.zeros(len(q_now)), qd]) if qd is not None else None
        elif np.max(np.abs(q[0] - q_now)) > 1e-3:
            raise Refused(
                f"{robot}: the first point (at 0 s) is {np.max(np.abs(q[0] - q_now)):.4f} rad from where the arm "
                "is; it must be within 0.001 rad, or later than 0 s"
            )
        else:
            q[0] = q_now
        self._check_limits(robot, t, q)
        valid = self._valid(robot)
        step = self.config.motion.collision_check_step
        for a, b in zip(q[:-1], q[1:], strict=True):
            if not segment_is_valid(a, b, valid, step):
                raise Refused(f"{robot}: the trajectory collides between {np.round(a, 3)} and {np.round(b, 3)} rad")
        plan = _sampled(t, q, qd, 1.0 / TRAJECTORY_RATE)
        sp = self._new_setpoint(robot, self.kinematics[robot].fk(q[-1]))
        result = SetpointResult(robot, sp.index, sp.frame, reached=False)
        for _ in self._run_plans({robot: sp}, {robot: plan}, {robot: q}, {robot: result}):
            pass  # the result is filled in, the trajectory announced; no view unless triggered
        self._record(result)
        self._uncaptured[robot] = sp
        return MoveResult(robot, sp.frame, result.reached, result.motion_s, result.contacts, result.reason)

    def capture(self, robot: str) -> Capture:
        """A view from ``robot``'s camera where the arm is now, rendered and saved as a run's
        views are (the frame of its last move, or a new one if that one has its view)."""
        self._check_arm(robot)
        q = np.asarray(self._physics.joint_positions(robot), float)
        world_T_camera = self.kinematics[robot].fk(q)
        sp = self._uncaptured[robot]
        if sp is None:  # nothing moved since the last view: a setpoint of its own, held in place
            sp = self._new_setpoint(robot, world_T_camera)
            t = self._physics.sim_time
            hold = JointTrajectory(np.array([t]), q[None, :])
            self.pm.hook.agrisim_trajectory(
                run=self._run, robot=robot, trajectory=Trajectory(robot, sp.index, q[None, :], hold, hold)
            )
            self._record(SetpointResult(robot, sp.index, sp.frame, reached=True, ee_error_mm=0.0, rot_error_rad=0.0))
        self._uncaptured[robot] = None
        return self._take_view(sp, world_T_camera)

    # ------------------------------------------------------------------ helpers
    def _check_arm(self, robot: str) -> None:
        if robot not in self.kinematics:
            raise Refused(f"no arm {robot!r}; the cell's arms: {', '.join(self.kinematics)}")

    def _new_setpoint(self, robot: str, world_T_camera: np.ndarray) -> Setpoint:
        sps = self.setpoints[robot]
        sp = Setpoint(robot, len(sps), np.asarray(world_T_camera, float))
        sps.append(sp)
        return sp

    def _record(self, result: SetpointResult) -> None:
        result.sim_time = self._physics.sim_time
        self._run.results.append(result)
        self.pm.hook.agrisim_setpoint(run=self._run, robot=result.robot, result=result)

    def _checked_trajectory(
        self,
        robot: str,
        names: Sequence[str],
        times: Sequence[float],
        positions: Sequence[Sequence[float]],
        velocities: Sequence[Sequence[float]] | None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The trajectory's times and rows in the arm's joint order, or a refusal saying what is
        malformed."""
        joints = self.joint_names(robot)
        if sorted(names) != sorted(joints):
            raise Refused(f"{robot}: joint names {list(names)}; expected each of {joints} once, in any order", "joints")
        if not len(times):
            raise Refused(f"{robot}: the trajectory has no points")
        order = [list(names).index(j) for j in joints]
        try:
            t = np.asarray(times, float)
            q = np.asarray(positions, float)[:, order] if len(positions) else np.zeros((0, len(joints)))
            qd = (
                np.asarray(velocities, float)[:, order]
                if velocities is not None and len(velocities) and all(len(v) for v in velocities)
                else None
            )
        except (ValueError, IndexError) as exc:
            raise Refused(
                f"{robot}: every point needs {len(joints)} positions (and velocities, if any): {exc}"
            ) from None
        if q.shape != (len(t), len(joints)) or (qd is not None and qd.shape != q.shape):
            raise Refused(f"{robot}: every point needs {len(joints)} positions (and velocities, if any)")
        if not (np.isfinite(t).all() and np.isfinite(q).all() and (qd is None or np.isfinite(qd).all())):
            raise Refused(f"{robot}: the trajectory holds a NaN or infinite value")
        if t[0] < 0 or np.any(np.diff(t) <= 0):
            raise Refused(f"{robot}: time_from_start must start at 0 s or later and increase strictly")
        return t, q, qd

    def _check_limits(self, robot: str, t: np.ndarray, q: np.ndarray) -> None:
        kin, joints = self.kinematics[robot], self.joint_names(robot)
        for j, name in enumerate(joints):
            lo, hi = kin.lower[j], kin.upper[j]
            bad = (q[:, j] < lo - 1e-9) | (q[:, j] > hi + 1e-9)
            if bad.any():
                v = q[np.argmax(bad), j]
                raise Refused(f"{robot}: {name} at {v:.4f} rad is beyond its limits [{lo:.4f}, {hi:.4f}] rad")
            speed = np.abs(np.diff(q[:, j])) / np.diff(t)
            limit = kin.velocity_limit[j] * self.config.motion.velocity_scale
            if len(speed) and speed.max() > limit * (1 + 1e-6):
                raise Refused(
                    f"{robot}: {name} would move at {speed.max():.3f} rad/s, above its limit of {limit:.3f} rad/s "
                    "(motion.velocity_scale of the joint's URDF velocity): give the points more time"
                )


def _sampled(t: np.ndarray, q: np.ndarray, qd: np.ndarray | None, dt: float) -> JointTrajectory:
    """The trajectory at the physics' rate: cubic through the points where velocities are given
    (as a trajectory controller's splines), else straight lines between them."""
    ts = np.append(np.arange(t[0], t[-1], dt), t[-1])
    if qd is not None and len(t) > 1:
        from scipy.interpolate import CubicHermiteSpline

        spline = CubicHermiteSpline(t, q, qd, axis=0)
        return JointTrajectory(ts, spline(ts), spline.derivative()(ts))
    qs = np.stack([np.interp(ts, t, q[:, j]) for j in range(q.shape[1])], axis=1)
    return JointTrajectory(ts, qs, np.gradient(qs, ts, axis=0) if len(ts) > 1 else np.zeros_like(qs))
