"""One episode of the routine: per setpoint IK -> plan -> time-parametrise -> execute -> reach
check -> capture, for both arms, announcing everything through event hooks.

The episode talks to backends only through :mod:`agrisim.interfaces`; sinks (Rerun, dataset
files) are plugins on the event hooks. A setpoint that cannot be reached is recorded with its
reason and the run goes on.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import functools
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pluggy

from agrisim.config import RunConfig
from agrisim.errors import ConfigError
from agrisim.evaluation.metrics import GroundTruth
from agrisim.evaluation.session import ReconSession, metrics_meta, summary_metrics
from agrisim.evaluation.views import View, load_frame, view_from_capture, view_of
from agrisim.files.atomic import remove_partial
from agrisim.files.exports import RUN_EXPORTS, build_exporter, run_export
from agrisim.files.rundir import prepare_out_dir, resolve_out_dir, saved_frames, saved_run
from agrisim.interfaces import (
    Capture,
    DepthSensor,
    Exposure,
    Imager,
    JointTrajectory,
    PhysicsBackend,
    Planner,
    PlanningFailed,
    Reconstructor,
    Renderer,
    Trajectory,
    view_key,
)
from agrisim.plant_choice import resolve_plant
from agrisim.records import Run, RunSummary, SetpointResult
from agrisim.registry import BackendSpec, Registry, blame, make_plugin_manager, with_own_plugins
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.segments import arms_stay_apart, segment_is_valid
from agrisim.robot.setpoints import Setpoint, routine
from agrisim.robot.trajectory import Limits, TimedPath, time_parametrize
from agrisim.scene.model import Scene
from agrisim.scene.transforms import pose_error
from agrisim.validation import OWN_RIGS, check_run, open_imager, open_rig

#: the entry point of the dataset sink (the run directory), which every run loads
DATASET_SINK = "sink-dataset"
#: rate at which planned trajectories are sampled for physics and sinks, Hz
TRAJECTORY_RATE = 240.0


class Episode:
    """A validated, ready-to-run episode. Building it checks every input and writes nothing."""

    def __init__(self, config: RunConfig, pm: pluggy.PluginManager | None = None) -> None:
        self.config = config
        self.pm = pm if pm is not None else make_plugin_manager()
        with_own_plugins(self.pm, names=(DATASET_SINK, *OWN_RIGS))  # whatever plugins are chosen
        self.registry = Registry(self.pm)
        self._prep_wall: dict[str, float] = {}
        checked = check_run(self.registry, config)
        self.physics_spec, self.physics_options = checked.physics
        self.planner_spec, self.planner_options = checked.planner
        self.sink_options = checked.sinks
        self.camera = checked.camera
        self.imager_spec = checked.imager
        self.out_dir = resolve_out_dir(config)
        # --resume replays the episode deterministically (the robot side is cheap) and renders
        # only the frames that are not complete on disk yet.
        self.done_frames: set[str] = set()
        self.saved_frames: dict[str, Any] = {}
        if config.output.resume:
            self.done_frames = set(saved_run(self.out_dir).get("frames_complete") or [])
            self.saved_frames = saved_frames(self.out_dir)
        self.rig, self.cell = open_rig(config, self.registry, checked.rig)
        self.setpoints = routine(self.cell, config.routine, self.rig.setpoints)
        self.kinematics = {arm.name: ArmKinematics(arm) for arm in self.cell.arms}
        m = config.motion
        self.limits = {
            arm.name: Limits(
                self.kinematics[arm.name].velocity_limit * m.velocity_scale,
                np.minimum(np.full(len(arm.joints), m.max_acceleration), arm.accelerations or np.inf),
                np.full(len(arm.joints), m.max_jerk),
            )
            for arm in self.cell.arms
        }
        # Rendering needs a plant and the room around it; a robot-only run (renderer "none")
        # builds neither (check_run has looked the plant up).
        self.renderer_spec = self.sensor_spec = self.recon_spec = None
        self.scene: Scene | None = None
        self.imagers: dict[str, Imager] = {}
        if checked.renderer is None:
            return
        self.renderer_spec, self.renderer_options = checked.renderer
        self._open_imagers()
        assert checked.sensor is not None and checked.room is not None
        self.sensor_spec, self.sensor_options = checked.sensor
        with _timed(self._prep_wall, "plant"):
            self.plant = resolve_plant(self.registry, config)
        room_spec, room_options = checked.room
        with _timed(self._prep_wall, "scene"), blame("room", room_spec, " building the scene"):
            room = self.registry.build("room", room_spec, self.cell, room_options)
            self.scene = room.scene(self.plant, seed=config.pcg_seed, labels=config.render.labels)
            self.scene.bench = list(self.plant.bench)  # (the room joined the bench's plants as one)
        if checked.recon is not None:
            self.recon_spec, self.recon_options = checked.recon

    def _open_imagers(self) -> None:
        """One imager per arm's camera (each has its own auto-exposure), fed the renderer's
        linear radiance; under ``--resume`` each goes on from the exposure of its arm's last
        frame on disk."""
        c = self.config.imager
        if c.model == "none":
            return
        # the record keeps the options as given; the renderer is built keeping radiance
        self._renderer_record = self.renderer_options
        self.keep_radiance = bool(getattr(self.renderer_options, "radiance", False))
        self.renderer_options = self.renderer_options.model_copy(update={"radiance": True})
        for arm in self.cell.arms:
            imager = open_imager(self.registry, c, self.config.seed)
            assert imager is not None
            self.imagers[arm.name] = imager
        if self.done_frames:
            for sp in (sp for sps in self.setpoints.values() for sp in sps):  # in shooting order
                shot = self.saved_frames.get(sp.frame, {}).get("exposure")
                if sp.frame in self.done_frames and shot is not None:
                    self.imagers[sp.robot].resume_from(Exposure.from_json(shot))

    # ------------------------------------------------------------------ running
    def run(self, progress: Callable[[int, int], None] | None = None) -> tuple[Run, RunSummary]:
        """Run the episode; returns the run (with per-setpoint results) and its summary."""
        run = self.open()
        status, error = "complete", ""
        try:
            self.start()
            steps = max(len(s) for s in self.setpoints.values())
            for k in range(steps):
                self.step(k)
                if progress:
                    progress(k + 1, steps)
            self.finish_reconstruction()
        except KeyboardInterrupt:
            status, error = "interrupted", "interrupted by the user"
            raise
        except Exception as exc:
            status, error = "failed", f"{type(exc).__name__}: {exc}"
            raise
        finally:
            summary = self.close(status, error)
        return run, summary

    def open(self) -> Run:
        """Build the backends, the output directory and the sinks; nothing has moved yet.
        :meth:`start` puts the arms home, :meth:`step` runs one setpoint, :meth:`close` reports
        and closes (an episode is opened once)."""
        # Backends first: if one cannot be built, nothing has been written yet. What is opened
        # is closed by close(), or here, in reverse, as soon as opening fails half-way.
        with ExitStack() as opened:
            physics: PhysicsBackend = self._build(opened, "physics", self.physics_spec, self.cell, self.physics_options)
            planner: Planner = self._build(None, "planner", self.planner_spec, self.planner_options)
            renderer: Renderer | None = None
            sensor: DepthSensor | None = None
            recon: Reconstructor | None = None
            if self.renderer_spec is not None:
                args = (self.scene, self.cell, self.config.render)
                renderer = self._build(opened, "renderer", self.renderer_spec, *args, self.renderer_options)
            if self.sensor_spec is not None:
                sensor = self._build(
                    opened, "sensor", self.sensor_spec, self.scene, self.cell, self.config.render, self.sensor_options
                )
            if self.recon_spec is not None:
                assert self.scene is not None  # a reconstructor is chosen only with a renderer, which has a scene
                recon = self._build(None, "reconstructor", self.recon_spec, self.scene.labels, self.recon_options)
            prepare_out_dir(self.out_dir, self.config)
            if self.config.output.resume:
                remove_partial(self.out_dir)  # half-written files of a killed run
            run = self._new_run(renderer, sensor, recon)
            self._sinks = self._register_sinks(run, opened)
            self._opened = opened.pop_all()  # (kept open: close() closes them)
        self._renderer, self._sensor = renderer, sensor
        self._physics, self._planner, self._run = physics, planner, run
        self._views: list[View] = []  # the last step's views (visit returns them)
        self._rng = np.random.default_rng(self.config.seed)
        return run

    def _build(self, opened: ExitStack | None, kind: str, spec: BackendSpec, *args: Any) -> Any:
        """Backend ``kind`` built from ``spec`` (its failure blamed on it); closed with the
        episode where ``opened`` is given."""
        with blame(kind, spec, " to start"):
            backend = self.registry.build(kind, spec, *args)
        if opened is not None:
            opened.callback(backend.close)
        return backend

    def _new_run(self, renderer: Renderer | None, sensor: DepthSensor | None, recon: Reconstructor | None) -> Run:
        """The run as events and sinks see it, and the reconstruction session of ``recon``."""
        run = Run(
            config=self.config,
            cell=self.cell,
            out_dir=self.out_dir,
            kinematics=self.kinematics,
            setpoints=self.setpoints,
            camera=self.camera,
            backends={"physics": self.physics_spec.name, "planner": self.planner_spec.name},
            backend_options={
                "physics": self.physics_options.model_dump(mode="json"),
                "planner": self.planner_options.model_dump(mode="json"),
            },
            started_at=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            # the scene as drawn, arms included: saved with the run for agrisim render
            scene=(
                dataclasses.replace(self.scene, arms=renderer.arm_meshes())
                if renderer is not None and self.scene is not None
                else self.scene
            ),
            labels=self.scene.labels if self.scene is not None else None,
            wall_s=dict(self._prep_wall),
            plant_notes=list(self.plant.notes) if self.scene is not None else [],
            exports=self._run_exports(),
        )
        if self.renderer_spec is not None:
            run.backends["renderer"] = self.renderer_spec.name
            record = self._renderer_record if self.imagers else self.renderer_options
            run.backend_options["renderer"] = record.model_dump(mode="json")
        if self.imagers:
            run.imager = next(iter(self.imagers.values())).describe()
        if sensor is not None and self.sensor_spec is not None:
            run.backends["sensor"] = self.sensor_spec.name
            run.backend_options["sensor"] = self.sensor_options.model_dump(mode="json")
            run.sensor = sensor.geometry(self.camera)
        self._session: ReconSession | None = None
        if recon is not None and self.scene is not None and self.recon_spec is not None:
            run.backends["recon"] = self.recon_spec.name
            run.backend_options["recon"] = self.recon_options.model_dump(mode="json")
            with _timed(run.wall_s, "truth"):
                truth = GroundTruth.of_scene(self.scene, self.config.metrics.truth_samples)
            self._session = ReconSession(
                recon,
                self.scene.labels,
                truth,
                self.config.metrics.thresholds_mm,
                on_cloud=lambda label, cloud, merged: self.pm.hook.agrisim_cloud(
                    run=run, label=label, cloud=cloud, merged=merged
                ),
                merged_every=self.config.recon.merged_every,
            )
        return run

    def start(self) -> None:
        """Put every arm at its home and announce the run (``agrisim_run_started``)."""
        for arm in self.cell.arms:
            self._physics.reset(arm.name, np.array(arm.home))
        self.pm.hook.agrisim_run_started(run=self._run)

    def step(self, k: int) -> None:
        """The ``k``-th setpoint of every arm that has one."""
        self._step({r: sps[k] for r, sps in self.setpoints.items() if k < len(sps)})

    def visit(self, targets: dict[str, Setpoint]) -> tuple[list[SetpointResult], list[View]]:
        """Move each arm of ``targets`` to its setpoint and take the view there, as a routine's
        step does (IK, planning, timing, physics, render, reconstruction), for setpoints chosen
        on the way rather than planned: a target not yet among the run's setpoints joins them
        (its ``index`` must be the arm's next). Returns the step's results and the views taken
        (an arm that did not reach its target takes none)."""
        for robot, sp in targets.items():
            planned = self.setpoints.setdefault(robot, [])
            if sp not in planned:
                if sp.index != len(planned):
                    raise ValueError(f"setpoint {sp.frame} is not {robot}'s next ({len(planned)})")
                planned.append(sp)
        before = len(self._run.results)
        self._step(targets)
        return self._run.results[before:], self._views

    def finish_reconstruction(self) -> dict[str, Any] | None:
        """The reconstruction of the views so far, finished and measured against the truth
        (the run's ``metrics.json`` content; None without a reconstructor)."""
        run = self._run
        if self._session is None or self.recon_spec is None:
            return None
        with self._stage("metrics"), blame("reconstructor", self.recon_spec, " to finish"):
            run.reconstruction, run.metrics = self._session.finish(metrics_meta(self.config))
        return run.metrics

    def look_from(self, world_T_camera: np.ndarray) -> View:
        """What the camera would see from ``world_T_camera`` with the arms left out, nothing
        moved, announced or written: a look ahead for planners that may use the truth."""
        if self._renderer is None:
            raise ConfigError("look_from needs a renderer")
        T = np.asarray(world_T_camera, float)
        images = self._renderer.render(self.camera, T, {})
        return View("look-ahead", self.camera, T, images.stored(self.config.render.depth_format != "png16"))

    @property
    def wall_s(self) -> dict[str, float]:
        """Seconds of wall time spent so far, by stage (ik, plan, execute, render, recon ...)."""
        return self._run.wall_s

    def joint_positions(self, robot: str) -> np.ndarray:
        """Where ``robot``'s joints are now, as the physics has them."""
        return self._physics.joint_positions(robot)

    def close(self, status: str, error: str = "") -> RunSummary:
        """Announce the end (``agrisim_run_finished``: the run's files are completed) and close
        the backends and the sinks; ``status`` is complete, interrupted or failed."""
        run, physics = self._run, self._physics
        summary = RunSummary(
            status=status,
            setpoints=len(run.results),
            reached=sum(r.reached for r in run.results),
            failed=sum(not r.reached for r in run.results),
            collisions=sum(bool(r.contacts) for r in run.results),
            sim_time=physics.sim_time,
            wall_s={k: round(v, 4) for k, v in run.wall_s.items()},
            error=error,
            metrics=summary_metrics(run.metrics) if run.metrics is not None else None,
        )
        with self._opened:  # the sinks unregistered, then the backends closed, last opened first
            self.pm.hook.agrisim_run_finished(run=run, summary=summary)
        return summary

    def _register_sinks(self, run: Run, opened: ExitStack) -> list[object]:
        """The dataset sink first (the run directory: resume, recon, export and compare need its
        files), then every other installed sink; each unregistered when the episode closes."""
        specs = self.registry.specs("sink")
        sinks: list[object] = []
        for name in sorted(specs, key=lambda n: n != "dataset"):
            sink = self.registry.build("sink", specs[name], run, self.sink_options[name])
            if sink is not None:
                self.pm.register(sink, name=f"sink:{name}:{run.run_id}")
                opened.callback(self.pm.unregister, sink)
                sinks.append(sink)
        self.pm.check_pending()
        return sinks

    def _run_exports(self) -> list[Callable[[Path], object]]:
        """The exports a rendered run writes itself at its end (:data:`RUN_EXPORTS`, those
        installed), built now with their default options."""
        installed = self.registry.specs("exporter")
        exports: list[Callable[[Path], object]] = []
        for name in RUN_EXPORTS:
            if name in installed:
                spec, exporter = build_exporter(self.registry, name)
                # the run's own directory: its earlier export (--resume, --overwrite) is replaced
                exports.append(functools.partial(run_export, spec, exporter, overwrite=True))
        return exports

    @contextmanager
    def _stage(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self._run.wall_s[name] = self._run.wall_s.get(name, 0.0) + time.perf_counter() - t0

    def _valid(self, robot: str, others: dict[str, np.ndarray] | None = None) -> Callable[[np.ndarray], bool]:
        physics, spec = self._physics, self.physics_spec

        def valid(q: np.ndarray) -> bool:
            try:  # free unless it raises; blamed on physics, not on the planner calling it
                return not physics.in_collision(robot, q, others)
            except Exception as exc:
                with blame("physics", spec, " in a collision query"):
                    raise exc

        return valid

    def _prepare_move(self, sp: Setpoint, result: SetpointResult) -> tuple[np.ndarray, TimedPath] | None:
        """IK and planning for one arm with the other arms where they are now."""
        kin = self.kinematics[sp.robot]
        q_now = self._physics.joint_positions(sp.robot)
        m = self.config.motion
        t0 = time.perf_counter()
        with self._stage("ik"):
            ik = kin.ik(
                sp.world_T_camera,
                q_now,
                is_valid=self._valid(sp.robot),
                rng=self._rng,
                restarts=m.ik_restarts,
                max_restarts=m.ik_max_restarts,
                iterations=m.ik_max_iterations,
                position_tolerance=m.reach_tolerance_mm * 1e-3,
                rotation_tolerance=m.reach_tolerance_rad,
            )
        result.ik_s += time.perf_counter() - t0
        if ik.q is None:  # not ik.ok, spelt so that ik.q is known to be set below
            result.reason = ik.reason
            return None
        # The nearest IK branch may be unreachable without a long detour (an elbow flip the
        # joint limits forbid, say); another often lies on a free straight line. Candidates
        # with a free straight line go first, nearest first; a few are tried before giving up.
        valid = self._valid(sp.robot)
        candidates = [ik.q, *ik.alternatives][: m.ik_candidates]
        with self._stage("plan"):
            # Only up to the first free line: checking every candidate's line would repeat,
            # per setpoint, work the planner does anyway.
            free = next(
                (i for i, g in enumerate(candidates) if segment_is_valid(q_now, g, valid, m.collision_check_step)),
                None,
            )
        if free:
            candidates.insert(0, candidates.pop(free))
        reasons = []
        path = None
        for goal in candidates:
            t0 = time.perf_counter()
            try:
                with self._stage("plan"), blame("planner", self.planner_spec, f" planning {sp.frame}"):
                    path = self._planner.plan(
                        q_now,
                        goal,
                        self._valid(sp.robot),
                        kin.lower,
                        kin.upper,
                        int(self._rng.integers(2**31)),
                        m.collision_check_step,
                    )
                break
            except PlanningFailed as exc:
                reasons.append(str(exc))
            finally:
                result.plan_s += time.perf_counter() - t0
        if path is None:
            result.reason = "plan: " + "; ".join(dict.fromkeys(reasons))
            return None
        with self._stage("parametrize"):
            timed = time_parametrize(path, self.limits[sp.robot])
        return path, timed

    def _step(self, targets: dict[str, Setpoint]) -> None:
        self._views = []
        results = {r: SetpointResult(r, sp.index, sp.frame, reached=False) for r, sp in targets.items()}
        moves: dict[str, tuple[np.ndarray, TimedPath]] = {}
        for robot, sp in targets.items():
            move = self._prepare_move(sp, results[robot])
            if move is not None:
                moves[robot] = move
        timed = {r: m[1] for r, m in moves.items()}
        with self._stage("joint_check"):
            apart = arms_stay_apart(self._physics, timed, self.limits, self.config.motion.collision_check_step)
        if apart:
            self._execute(targets, moves, results)
        else:
            # Together they would collide: the first arm moves, the others wait and re-plan.
            order = list(moves)
            self._execute(targets, {order[0]: moves[order[0]]}, results)
            for robot in order[1:]:
                results[robot] = SetpointResult(robot, targets[robot].index, targets[robot].frame, False, waited=True)
                move = self._prepare_move(targets[robot], results[robot])
                if move is not None:
                    self._execute(targets, {robot: move}, results)
        for robot, res in results.items():
            if robot not in moves and not res.reason:
                res.reason = "not moved"
            res.sim_time = self._physics.sim_time
            self._run.results.append(res)
            self.pm.hook.agrisim_setpoint(run=self._run, robot=robot, result=res)

    def _link_poses(self) -> dict[str, dict[str, np.ndarray]]:
        """``world_T_link`` of every arm link where the physics has the arms now."""
        return {r: k.link_poses(self._physics.joint_positions(r)) for r, k in self.kinematics.items()}

    def _execute(
        self,
        targets: dict[str, Setpoint],
        moves: dict[str, tuple[np.ndarray, TimedPath]],
        results: dict[str, SetpointResult],
    ) -> None:
        if not moves:
            return
        plans = {r: timed.discretize(1.0 / TRAJECTORY_RATE) for r, (_, timed) in moves.items()}
        for robot, world_T_camera in self._run_plans(targets, plans, {r: p for r, (p, _) in moves.items()}, results):
            if results[robot].reached:
                self._take_view(targets[robot], world_T_camera)

    def _run_plans(
        self,
        targets: dict[str, Setpoint],
        plans: dict[str, JointTrajectory],
        paths: dict[str, np.ndarray],
        results: dict[str, SetpointResult],
    ) -> Iterator[tuple[str, np.ndarray]]:
        """Execute the arms' sampled plans together, each settled when its camera is at its
        target; then, arm by arm, fill in its result, announce its trajectory and yield where
        its camera ended (``world_T_camera``), so that the caller's view of one arm comes
        before the next arm's trajectory is announced."""
        m = self.config.motion
        tol_p, tol_r = m.reach_tolerance_mm * 1e-3, m.reach_tolerance_rad
        kin = self.kinematics

        def settled(robot: str, q: np.ndarray) -> bool:
            ep, er = pose_error(kin[robot].fk(q), targets[robot].world_T_camera)
            return ep <= tol_p and er <= tol_r

        t_start = self._physics.sim_time
        with self._stage("execute"), blame("physics", self.physics_spec, " executing a trajectory"):
            executions = self._physics.execute(plans, settled, m.reach_timeout)
        for robot, ex in executions.items():
            res = results[robot]
            world_T_camera = kin[robot].fk(self._physics.joint_positions(robot))
            ep, er = pose_error(world_T_camera, targets[robot].world_T_camera)
            res.ee_error_mm = ep * 1e3
            res.rot_error_rad = er
            res.motion_s = plans[robot].duration + ex.settle_time
            res.contacts = sorted(set(ex.contacts))
            res.reached = ex.settled and not ex.contacts
            if not ex.settled:
                res.reason = f"not settled within {m.reach_timeout:g} s (error {ep * 1e3:.4f} mm, {er:.2e} rad)"
            elif ex.contacts:
                res.reason = f"collision while moving: {', '.join(res.contacts)}"
            self.pm.hook.agrisim_trajectory(
                run=self._run,
                robot=robot,
                trajectory=Trajectory(
                    robot, targets[robot].index, paths[robot], plans[robot].shifted(t_start), ex.executed
                ),
            )
            yield robot, world_T_camera

    def _take_view(self, target: Setpoint, world_T_camera: np.ndarray) -> Capture:
        """The view of ``target``'s arm from ``world_T_camera``: rendered (or, under --resume,
        read back when complete on disk), announced (``agrisim_capture``) and reconstructed."""
        capture = Capture(
            robot=target.robot,
            frame=target.frame,
            setpoint=target.index,
            sim_time=self._physics.sim_time,
            world_T_camera=world_T_camera,
            camera=self.camera,
            link_poses=self._link_poses() if self._renderer is not None else None,
        )
        view: View | None = None
        if capture.frame in self.done_frames:
            # complete on disk from before --resume: read back, not rendered again, so
            # the recording and the reconstruction see exactly the saved frame
            capture.replayed = True
            if self._renderer is not None:
                capture.images = load_frame(self.out_dir, capture.frame, self.camera)
                view = view_of(capture, self.config.recon.depth)
            if self.imagers:
                capture.exposure = self.saved_frames.get(capture.frame, {}).get("exposure")
        elif self._renderer is not None and self.renderer_spec is not None:
            with self._stage("render"), blame("renderer", self.renderer_spec, f" rendering {capture.frame}"):
                capture.images = self._renderer.render(self.camera, world_T_camera, capture.link_poses or {})
            if self.imagers:
                with self._stage("imager"):
                    self._shoot(capture)
            if self._sensor is not None and self.sensor_spec is not None:
                with self._stage("sensor"), blame("sensor", self.sensor_spec, f" measuring {capture.frame}"):
                    capture.images.depth_sensor = self._sensor.measure(
                        self.camera, world_T_camera, capture.link_poses or {}, capture.images
                    )
            view = view_from_capture(capture, self.config.render.depth_format != "png16", self.config.recon.depth)
        with self._stage("capture"):
            self.pm.hook.agrisim_capture(run=self._run, capture=capture)
        if self._session is not None and view is not None and self.recon_spec is not None:
            with self._stage("recon"), blame("reconstructor", self.recon_spec, f" integrating {capture.frame}"):
                self._session.add(view)
        if view is not None:
            self._views.append(view)
        return capture

    def _shoot(self, capture: Capture) -> None:
        """The imager's shot of the rendered radiance in place of the noise-free RGB."""
        images = capture.images
        assert images is not None and images.radiance is not None, "the renderer kept no radiance"
        shot = self.imagers[capture.robot].shoot(images.radiance, view_key(capture.frame))
        images.rgb = shot.rgb
        images.raw = shot.raw if self.config.imager.raw else None
        if not self.keep_radiance:
            images.radiance = None
        capture.exposure = shot.exposure.to_json()


@contextmanager
def _timed(store: dict[str, float], name: str) -> Iterator[None]:
    t0 = time.perf_counter()
    try:
        yield
    finally:
        store[name] = store.get(name, 0.0) + time.perf_counter() - t0


def run_episode(config: RunConfig, *, pm: pluggy.PluginManager | None = None) -> tuple[Run, RunSummary]:
    """Validate ``config``, run one episode, and return the run and its summary."""
    return Episode(config, pm).run()


__all__ = ["TRAJECTORY_RATE", "Episode", "run_episode"]
