"""``agrisim render``: draw the RGB of a finished run again with another renderer, from what the
run saved, and nothing else.

A run saves the scene as drawn (``scene/lab.glb``: room, clutter, table, pot, plant, lights and
the arms' link meshes), every frame's camera pose (``cameras.json``) and arm link poses
(``link_poses/<frame>.json``). From these a renderer that declares the ``rerender`` capability
draws each frame's RGB (:meth:`agrisim.interfaces.Renderer.render_rgb`) with no physics,
kinematics, planning or Open3D: a GPU machine with agrisim's core, numpy, Pillow and the
renderer's own library (Mitsuba) is enough.

The output is a complete dataset: every file of the source (labels, depth, instances, clouds,
metrics, exports, the scene) carried over (hard links where the filesystem allows, else copies)
and the RGB re-rendered (with its radiance when the renderer keeps it); the Rerun recording and
the source's radiance are not carried (they hold the old light).
``render.json`` records what was re-rendered with which options and which frames are done, so
an interrupted re-render resumes frame by frame. Nothing is replaced without ``--overwrite``.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.files.atomic import write_json
from agrisim.files.dataset import write_png
from agrisim.files.exr import write_exr
from agrisim.files.point_cloud import load_point_plant
from agrisim.files.rundir import camera_from_json, read_json, read_run
from agrisim.files.scene_glb import read_scene
from agrisim.interfaces import CameraModel, Renderer

RENDER_JSON = "render.json"
#: files of the source not carried into a re-rendered dataset (they show the old RGB)
NOT_CARRIED = {layout.RECORDING, RENDER_JSON}


def _link_poses(run_dir: Path, frame: str) -> dict[str, dict[str, np.ndarray]]:
    doc = read_json(layout.link_poses(run_dir, frame), "the arms' link poses of this frame")
    return {robot: {link: np.asarray(T, np.float64) for link, T in links.items()} for robot, links in doc.items()}


#: folders of the source not carried: its RGB, and what was made from it (COLMAP's model of
#: those images, the bag that holds them)
NOT_CARRIED_FOLDERS = {"rgb", layout.RADIANCE, layout.COLMAP, layout.ROSBAG}


def _carry(source: Path, out: Path) -> None:
    """Every file of ``source`` but its RGB and what shows it (:data:`NOT_CARRIED`,
    :data:`NOT_CARRIED_FOLDERS`) into ``out`` (hard links, else copies)."""
    for root, dirs, files in os.walk(source):
        rel = Path(root).relative_to(source)
        if rel.parts[:1] and rel.parts[0] in NOT_CARRIED_FOLDERS:
            dirs.clear()
            continue
        (out / rel).mkdir(parents=True, exist_ok=True)
        for name in files:
            if rel == Path(".") and name in NOT_CARRIED:
                continue
            src, dst = Path(root) / name, out / rel / name
            if dst.exists():
                continue
            try:
                os.link(src, dst)  # every writer replaces files atomically: a shared inode is safe
            except OSError:
                shutil.copy2(src, dst)


class RenderPlan:
    """A checked re-render of one run: the renderer, its options, the frames, the output (the
    constructor refuses bad input before anything is written)."""

    def __init__(
        self, run_dir: Path, renderer: str, overrides: dict[str, Any], out: Path | None, overwrite: bool
    ) -> None:
        from agrisim.config import backend_options, build_config
        from agrisim.registry import Registry, make_plugin_manager

        self.run_dir = Path(run_dir).expanduser()
        run, self.cameras = read_run(self.run_dir)
        saved = run.get("config")
        if not isinstance(saved, dict):
            raise UserError(f"{self.run_dir / layout.RUN_JSON} holds no run configuration")
        unknown = set(overrides) - {"renderer"}
        if unknown:
            raise UserError(f"agrisim render takes only renderer.* settings, not {', '.join(sorted(unknown))}")
        saved = {k: v for k, v in saved.items() if k not in ("output", "renderer")}
        self.config = build_config(saved, {"renderer": {"backend": renderer, **overrides.get("renderer", {})}})
        registry = Registry(make_plugin_manager())
        self.spec = registry.get("renderer", renderer)
        if not getattr(self.spec.capabilities, "rerender", False):
            able = [n for n, s in registry.specs("renderer").items() if getattr(s.capabilities, "rerender", False)]
            raise UserError(
                f"renderer {renderer!r} cannot re-render a saved run (it draws RGB only with its own pass); "
                f"renderers that can: {', '.join(able) or 'none installed'}"
            )
        self.config.renderer.check_tables("renderer", registry.specs("renderer"))
        self.options = backend_options(
            self.spec.options_model, self.config.renderer.options_for(renderer), f"renderer {renderer!r}"
        )
        scene_path = self.run_dir / layout.SCENE_GLB
        if not scene_path.is_file():
            raise UserError(
                f"the run in {self.run_dir} has no saved scene ({layout.SCENE_GLB}): it was made by an older agrisim "
                "or without a renderer; run it again to re-render it"
            )
        self.scene_path = scene_path
        self.points_path = self.run_dir / layout.PLANT_POINTS
        if self.points_path.is_file() and not getattr(self.spec.capabilities, "points", False):
            able = [
                n
                for n, sp in registry.specs("renderer").items()
                if getattr(sp.capabilities, "rerender", False) and getattr(sp.capabilities, "points", False)
            ]
            raise UserError(
                f"the run in {self.run_dir} draws its plant as points, which renderer {renderer!r} cannot draw; "
                f"renderers that can re-render point plants: {', '.join(able) or 'none installed'}"
            )
        self.frames = [f for f in run.get("frames_complete") or [] if f in self.cameras["frames"]]
        if not self.frames:
            raise UserError(f"the run in {self.run_dir} has no rendered frames")
        if not self.config.render.hide_robots:
            lacking = [f for f in self.frames if not layout.link_poses(self.run_dir, f).is_file()]
            if lacking:
                raise UserError(
                    f"the run in {self.run_dir} saved no arm link poses for {len(lacking)} frames "
                    f"({lacking[0]}, ...): it was made by an older agrisim; run it again to re-render it"
                )
        self.out = (
            Path(out).expanduser() if out is not None else self.run_dir.with_name(f"{self.run_dir.name}-{renderer}")
        )
        self.in_place = self.out.resolve() == self.run_dir.resolve()
        self.record = {
            "source": str(self.run_dir.resolve()),
            "renderer": renderer,
            "options": self.options.model_dump(mode="json"),
        }
        self.done: list[str] = self._check_out(overwrite)
        if self.spec.preflight is not None:
            self.spec.preflight(self.config, self.options)

    def _check_out(self, overwrite: bool) -> list[str]:
        """Frames already re-rendered in the output by this very re-render (resume); refuses an
        output that holds anything else unless ``overwrite``."""
        out = self.out
        if out.exists() and not out.is_dir():
            raise OutputError(f"--out {out} exists and is not a directory")
        source, target = self.run_dir.resolve(), out.resolve()
        if not self.in_place and (source in target.parents or target in source.parents):
            raise OutputError(f"--out {out} must not lie inside the run {self.run_dir} nor contain it")
        previous = out / RENDER_JSON
        if previous.is_file():
            doc = read_json(previous, "")
            if all(doc.get(k) == v for k, v in self.record.items()):
                return [f for f in doc.get("frames_done") or [] if f in self.frames]
        if self.in_place:
            if not overwrite:
                raise OutputError(
                    "re-rendering into the run itself replaces its RGB; pass --overwrite to do so, or --out DIR"
                )
            return []
        if out.exists() and any(out.iterdir()) and not overwrite:
            raise OutputError(f"--out {out} already exists; pass --overwrite to replace it")
        return []

    def renderer(self) -> tuple[Renderer, CameraModel]:
        """The renderer, on the saved scene, and the run's camera."""
        scene = read_scene(self.scene_path)
        if self.points_path.is_file():  # the plant as drawn: points, saved beside the scene
            scene.points = load_point_plant(self.points_path, place=False, up="z").points
        renderer = self.spec.factory(scene, None, self.config.render, self.options)
        return renderer, camera_from_json(self.cameras["intrinsics"])

    def run(self, progress: Callable[[int, int], None] | None = None) -> Path:
        """Re-render every frame not done yet; returns the output directory."""
        out = self.out
        if not self.in_place:
            if out.exists() and not self.done:
                shutil.rmtree(out)
            out.mkdir(parents=True, exist_ok=True)
            _carry(self.run_dir, out)
        record: dict[str, Any] = dict(self.record, status="running", frames_done=list(self.done))
        write_json(out / RENDER_JSON, record)
        settings = self.config.render
        renderer, camera = self.renderer()
        todo = [f for f in self.frames if f not in set(self.done)]

        def save(frame: str, rgb: np.ndarray, radiance: np.ndarray | None) -> None:
            # one writer thread: frames are listed done in order, each after its PNG exists
            if radiance is not None:
                write_exr(layout.radiance(out, frame), radiance)
            write_png(layout.image(out, "rgb", frame), rgb)
            record["frames_done"].append(frame)
            write_json(out / RENDER_JSON, record)
            if progress is not None:
                progress(len(record["frames_done"]), len(self.frames))

        # The PNG of one frame is encoded while the next renders (on a GPU, encoding a 1080p
        # PNG takes about as long as path tracing it).
        with ThreadPoolExecutor(1) as writer:
            pending: list[Future[None]] = []
            try:
                for frame in todo:
                    T = np.asarray(self.cameras["frames"][frame]["world_T_camera"], np.float64)
                    poses = {} if settings.hide_robots else _link_poses(self.run_dir, frame)
                    rgb, radiance = renderer.render_rgb(camera, T, poses)
                    while pending and (pending[0].done() or len(pending) > 2):  # at most 2 frames queued
                        pending.pop(0).result()  # (a failed write is raised here)
                    pending.append(writer.submit(save, frame, rgb, radiance))
            finally:
                renderer.close()
            for f in pending:
                f.result()
        record["status"] = "complete"
        write_json(out / RENDER_JSON, record)
        return out


def _render_task(run_dir: str, renderer: str, overrides: dict[str, Any], overwrite: bool) -> dict[str, Any]:
    """One run's re-render in a Ray worker (checked again there: the worker's files are what
    count), returning what it did."""
    plan = RenderPlan(Path(run_dir), renderer, overrides, None, overwrite)
    out = plan.run()
    return {"run": run_dir, "out": str(out), "frames": len(plan.frames)}


def render_runs(
    plans: list[RenderPlan],
    overrides: dict[str, Any],
    overwrite: bool,
    ray_address: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict[str, Any]]:
    """Several checked re-renders as Ray tasks, one GPU each where the cluster has GPUs. Returns
    one record per run, in order."""
    from agrisim.app.compare import start_ray, stop_ray

    info = start_ray(workers=None, address=ray_address)
    try:
        import ray

        resources = ray.cluster_resources()
        # Mitsuba's CPU variant spreads one render over every core, so CPU tasks ask for one
        # CPU each and share the cores (their start-up, JIT compiling, overlaps this way)
        need: dict[str, Any] = {"num_gpus": 1} if resources.get("GPU", 0) >= 1 else {"num_cpus": 1}
        task = ray.remote(max_retries=0, **need)(_render_task)
        refs = {task.remote(str(p.run_dir), p.spec.name, overrides, overwrite): i for i, p in enumerate(plans)}
        records: list[dict[str, Any]] = [{} for _ in plans]
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            i = refs[ready[0]]
            try:
                records[i] = ray.get(ready[0])
            except ray.exceptions.RayTaskError as exc:
                records[i] = {
                    "run": str(plans[i].run_dir),
                    "error": str(exc.cause if exc.cause else exc).splitlines()[0],
                }
            if progress is not None:
                progress(len(plans) - len(pending), len(plans))
        return records
    finally:
        stop_ray(info)
