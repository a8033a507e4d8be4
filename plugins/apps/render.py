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

Several runs, or one run on several GPUs, go to Ray (:func:`render_runs`): a task per run, or a
run's frames dealt out over the GPUs (:func:`agrisim.plugins.apps.placement.split_frames`). Each part
lists the frames it has done in ``render.part-<k>.json`` beside ``render.json`` (one writer a
file, so none can lose another's record); a resumed or retried part reads them back, and when
every part of a run is done they are merged into ``render.json`` and removed.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.files.atomic import write_json
from agrisim.files.exr import write_exr
from agrisim.files.rundir import camera_from_json, read_json, read_run
from agrisim.interfaces import CameraModel, Renderer
from agrisim.plugins.formats.point_cloud import load_point_plant
from agrisim.plugins.formats.scene_glb import read_scene
from agrisim.plugins.sinks.dataset.writer import write_png

RENDER_JSON = "render.json"
#: files of the source not carried into a re-rendered dataset (they show the old RGB)
NOT_CARRIED = {layout.RECORDING, RENDER_JSON}
#: where the part ``k`` of a re-render split over GPUs lists its frames done
PART_JSON = "render.part-{}.json"


def _link_poses(run_dir: Path, frame: str) -> dict[str, dict[str, np.ndarray]]:
    doc = read_json(layout.link_poses(run_dir, frame), "the arms' link poses of this frame")
    return {robot: {link: np.asarray(T, np.float64) for link, T in links.items()} for robot, links in doc.items()}


#: folders of the source not carried: its RGB, and what was made from it (COLMAP's model of
#: those images, the bag that holds them)
NOT_CARRIED_FOLDERS = {"rgb", layout.RADIANCE, layout.RAW, layout.COLMAP, layout.ROSBAG}


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
            if rel == Path(".") and (name in NOT_CARRIED or Path(name).match(PART_JSON.format("*"))):
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
        from agrisim.validation import imager_spec

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
        self.imager_spec = imager_spec(registry, self.config.imager)
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
        # what the run needs of a re-renderer, beyond re-rendering: (capability, what, the run has it)
        needs = [
            ("points", "draws its plant as points, which renderer {r} cannot draw", "re-render point plants"),
            ("lenses", "has a distorting lens, which renderer {r} cannot draw through", "re-render through a lens"),
            ("radiance", "has an imager, which needs the linear radiance renderer {r} does not keep", "feed an imager"),
        ]
        has = {
            "points": self.points_path.is_file(),
            "lenses": self.cameras["intrinsics"].get("distortion") is not None,
            "radiance": self.config.imager.model != "none",
        }
        for capability, lacks, can in needs:
            if has[capability] and not getattr(self.spec.capabilities, capability, False):
                able = [
                    n
                    for n, sp in registry.specs("renderer").items()
                    if getattr(sp.capabilities, "rerender", False) and getattr(sp.capabilities, capability, False)
                ]
                raise UserError(
                    f"the run in {self.run_dir} {lacks.format(r=repr(renderer))}; "
                    f"renderers that can {can}: {', '.join(able) or 'none installed'}"
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
                done = set(doc.get("frames_done") or []) | self.parts_done()
                return [f for f in self.frames if f in done]
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
        options = self.options
        if self.config.imager.model != "none":  # the imager shoots the radiance
            options = options.model_copy(update={"radiance": True})
        renderer = self.spec.factory(scene, None, self.config.render, options)
        return renderer, camera_from_json(self.cameras["intrinsics"])

    def _shoot(self, frame: str, radiance: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """(RGB, raw) of ``frame``'s radiance through the run's imager, at the exposure the run
        recorded for it and with its noise: the camera shot again, under the new light."""
        from agrisim.interfaces import Exposure, view_key

        spec = self.imager_spec
        assert spec is not None and radiance is not None
        imager = spec.factory(self.config.imager, self.config.seed, spec.options_model())
        recorded = self.cameras["frames"][frame].get("exposure")
        if recorded is not None:
            imager = imager.at_exposure(Exposure.from_json(recorded))
        shot = imager.shoot(radiance, view_key(frame))
        return shot.rgb, (shot.raw if self.config.imager.raw else None)

    def _parts(self) -> list[Path]:
        return sorted(self.out.glob(PART_JSON.format("*")))

    def _part_record(self, path: Path) -> list[str]:
        """The frames a part file lists done, if it belongs to this very re-render."""
        try:
            doc = read_json(path, "")
        except UserError:  # a part file cut short by a lost machine: its frames are drawn again
            return []
        return list(doc.get("frames_done") or []) if all(doc.get(k) == v for k, v in self.record.items()) else []

    def parts_done(self) -> set[str]:
        """The frames the part files of this re-render list done."""
        return {f for path in self._parts() for f in self._part_record(path)}

    def prepare(self) -> None:
        """The output made ready to draw into: replaced (a checked ``--overwrite``) or kept (a
        resume), the source's files carried in, ``render.json`` written with status running."""
        out = self.out
        if not self.in_place:
            if out.exists() and not self.done:
                shutil.rmtree(out)
            out.mkdir(parents=True, exist_ok=True)
            _carry(self.run_dir, out)
        for path in self._parts() if not self.done else []:
            path.unlink()  # a replaced re-render's parts
        write_json(out / RENDER_JSON, dict(self.record, status="running", frames_done=list(self.done)))

    def render_frames(
        self,
        frames: list[str],
        part: int | None = None,
        progress: Callable[[int, int], None] | None = None,
        on_frame: Callable[[str], None] | None = None,
    ) -> list[str]:
        """Draw ``frames`` (those not done yet) into the prepared output, each listed done in
        ``render.json``, or, for ``part`` k of a split re-render, in its own part file (which a
        retried part reads back). ``on_frame(frame)`` hears of each frame listed done. Returns
        the frames drawn now."""
        out = self.out
        if part is None:
            path = out / RENDER_JSON
            record: dict[str, Any] = read_json(path, "")
        else:
            path = out / PART_JSON.format(part)
            done = self._part_record(path) if path.is_file() else []
            record = dict(self.record, part=part, frames_done=done)
        already = set(record["frames_done"]) | set(self.done)
        todo = [f for f in frames if f not in already]
        settings = self.config.render
        renderer, camera = self.renderer()

        imaging = self.config.imager.model != "none"
        keep_radiance = bool(getattr(self.options, "radiance", False))

        def save(frame: str, rgb: np.ndarray, radiance: np.ndarray | None, raw: np.ndarray | None) -> None:
            # one writer thread: frames are listed done in order, each after its PNG exists
            if radiance is not None and keep_radiance:
                write_exr(layout.radiance(out, frame), radiance)
            if raw is not None:
                write_png(layout.image(out, layout.RAW, frame), raw)
            write_png(layout.image(out, "rgb", frame), rgb)
            record["frames_done"].append(frame)
            write_json(path, record)
            if on_frame is not None:
                on_frame(frame)
            if progress is not None:
                progress(len(record["frames_done"]), len(self.frames))

        def views() -> Iterator[tuple[np.ndarray, dict[str, dict[str, np.ndarray]]]]:
            for frame in todo:
                T = np.asarray(self.cameras["frames"][frame]["world_T_camera"], np.float64)
                yield T, ({} if settings.hide_robots else _link_poses(self.run_dir, frame))

        # The PNG of one frame is encoded while the next renders (on a GPU, encoding a 1080p
        # PNG takes about as long as path tracing it), and a GPU renderer starts the next
        # frame before handing over this one (render_rgb_stream).
        with ThreadPoolExecutor(1) as writer:
            pending: list[Future[None]] = []
            try:
                for frame, (rgb, radiance) in zip(todo, renderer.render_rgb_stream(camera, views()), strict=True):
                    raw = None
                    if imaging:
                        rgb, raw = self._shoot(frame, radiance)
                    while pending and (pending[0].done() or len(pending) > 2):  # at most 2 frames queued
                        pending.pop(0).result()  # (a failed write is raised here)
                    pending.append(writer.submit(save, frame, rgb, radiance, raw))
            finally:
                renderer.close()
            for f in pending:
                f.result()
        return todo

    def finish(self) -> list[str]:
        """Merge the parts' records into ``render.json``; ``status`` complete where every frame
        is done. Returns the frames not done (empty when complete)."""
        doc = read_json(self.out / RENDER_JSON, "")
        done = set(doc.get("frames_done") or []) | self.parts_done()
        doc["frames_done"] = [f for f in self.frames if f in done]
        missing = [f for f in self.frames if f not in done]
        doc["status"] = "running" if missing else "complete"
        write_json(self.out / RENDER_JSON, doc)
        if not missing:
            for path in self._parts():
                path.unlink()
        return missing

    @property
    def device(self) -> str:
        """``gpu``, ``auto`` or ``cpu``: where the renderer draws, by its ``variant`` option."""
        return {"cuda": "gpu", "auto": "auto"}.get(str(getattr(self.options, "variant", None)), "cpu")

    def run(self, progress: Callable[[int, int], None] | None = None) -> Path:
        """Re-render every frame not done yet, in this process; returns the output directory."""
        self.prepare()
        self.render_frames(self.frames, progress=progress)
        self.finish()
        return self.out


#: Ray retries a part whose worker or node was lost this many times (it resumes from its part
#: file); an exception raised by the renderer is recorded, never retried
MAX_RETRIES = 3

PartTask = Callable[..., dict[str, Any]]


def render_part_task(
    run_dir: str,
    renderer: str,
    overrides: dict[str, Any],
    out: str,
    frames: list[str],
    part: int,
    on_frame: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Part ``part`` of a re-render in a Ray worker: ``frames`` of ``run_dir`` drawn into the
    output the driver prepared (checked again here: the worker's files are what count).
    Returns where it ran and what it drew."""
    import socket
    import time

    t0 = time.perf_counter()
    plan = RenderPlan(Path(run_dir), renderer, overrides, Path(out), overwrite=False)
    record: dict[str, Any] = {"run": run_dir, "part": part, "host": socket.gethostname(), "pid": os.getpid()}
    try:
        import ray

        if ray.is_initialized():
            record["resources"] = ray.get_runtime_context().get_assigned_resources()
            record["gpu_ids"] = [str(i) for i in ray.get_gpu_ids()]  # what CUDA_VISIBLE_DEVICES names
    except ImportError:  # pragma: no cover - called outside Ray (debugging)
        pass
    drawn = plan.render_frames(frames, part=part, on_frame=on_frame)
    record.update(frames=len(frames), drawn=drawn, seconds=round(time.perf_counter() - t0, 3))
    return record


# Long because Ray's submit/wait loop shares its state (pending parts, records, progress).
def render_runs(
    plans: list[RenderPlan],
    overrides: dict[str, Any],
    ray_address: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    *,
    gpus: int | None = None,
    gpu_resource: str = "GPU",
    task: PartTask = render_part_task,
) -> list[dict[str, Any]]:
    """Checked re-renders as Ray tasks: one GPU each, and a run's frames split over several GPUs
    where there are fewer runs than GPUs (:func:`agrisim.plugins.apps.placement.split_frames`); on a
    cluster without GPUs, one task a run. ``gpus`` caps the GPUs used (default: every
    ``gpu_resource`` of the cluster; more than it has is a UserError raised before anything is
    written). ``progress(views_done, views)`` hears of the frames drawn about once a second.
    Returns one record per run, in order: its output, frames, parts, or its error. ``task`` is
    the body of each part (:func:`render_part_task`; tests wrap it)."""
    import time

    from agrisim.plugins.apps.compare import start_ray, stop_ray
    from agrisim.plugins.apps.placement import split_frames, task_resources

    if gpus is not None and gpus < 1:
        raise UserError(f"--gpus must be 1 or more, got {gpus}")
    info = start_ray(workers=None, address=ray_address)
    try:
        import ray

        have = int(ray.cluster_resources().get(gpu_resource, 0))
        if gpus is not None and gpus > have:
            raise UserError(f"--gpus {gpus}: the Ray cluster has {have} {gpu_resource} resource{'s' * (have != 1)}")
        gpu = have > 0 and any(p.device != "cpu" for p in plans)
        lacking = [p for p in plans if p.device == "gpu"]
        if lacking and not gpu:
            raise UserError(f"renderer variant cuda asks for a GPU but the Ray cluster has no {gpu_resource} resource")
        todo = [[f for f in p.frames if f not in set(p.done)] for p in plans]
        # Mitsuba's CPU variant spreads one render over every core: on CPUs a task a run, each
        # asking for one core, so that their start-up (JIT compiling) overlaps
        parts = split_frames(todo, (gpus or have) if gpu else len(plans))
        for p in plans:
            p.prepare()
        remote: Any = ray.remote(max_retries=MAX_RETRIES, **task_resources(gpu, gpu_resource))(task)
        pending = {
            remote.remote(str(plans[i].run_dir), plans[i].spec.name, overrides, str(plans[i].out), frames, k): i
            for i, k, frames in parts
            if frames
        }
        records: list[dict[str, Any]] = [
            {"run": str(p.run_dir), "out": str(p.out), "frames": len(p.frames), "parts": []} for p in plans
        ]
        total = sum(len(p.frames) for p in plans)
        last = 0.0
        while pending:
            try:
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=1.0)
            except KeyboardInterrupt:  # a cluster's workers would draw on: the parts are stopped
                for ref in pending:
                    ray.cancel(ref, force=True)
                raise
            for ref in ready:
                i = pending.pop(ref)
                try:
                    records[i]["parts"].append(ray.get(ref))
                except ray.exceptions.RayError as exc:
                    cause = getattr(exc, "cause", None) or exc
                    records[i].setdefault("error", (str(cause).strip().splitlines() or [type(exc).__name__])[0])
            if progress is not None and (ready or time.monotonic() - last > 1.0):
                last = time.monotonic()
                progress(sum(len(set(p.done) | p.parts_done()) for p in plans), total)
        missing = 0
        for p, record in zip(plans, records, strict=True):
            left = p.finish()
            missing += len(left)
            if left and "error" not in record:
                record["error"] = f"{len(left)} frames not drawn"
        if progress is not None:
            progress(total - missing, total)
        return records
    finally:
        stop_ray(info)
