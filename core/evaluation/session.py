"""Reconstruction of a run, during the run or afterwards from its dataset on disk.

:class:`ReconSession` feeds views to a reconstructor backend, counts what the metrics need, and
passes per-view and merged clouds on (to the ``agrisim_cloud`` hook in a run). The episode uses
it view by view; ``agrisim recon RUN_DIR`` (:func:`rebuild`) replays a saved dataset through
the same session. :func:`write_reconstruction` writes ``clouds/`` and ``metrics.json``.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agrisim.capabilities import check_reconstructor
from agrisim.config import depth_read
from agrisim.errors import OutputError, UserError
from agrisim.evaluation.metrics import GroundTruth, ViewStats, evaluate
from agrisim.evaluation.views import View, load_view
from agrisim.files import layout
from agrisim.files.atomic import write_bytes, write_json, write_through
from agrisim.files.rundir import camera_from_json, read_run
from agrisim.interfaces import ALL, Cloud, Reconstruction, Reconstructor, SurfaceMesh
from agrisim.scene.model import LabelTable

if TYPE_CHECKING:
    from agrisim.config import RunConfig
    from agrisim.registry import Registry

CloudCallback = Callable[[str, Cloud, bool], None]


class ReconSession:
    """One reconstruction fed view by view, with the counts its metrics need.

    ``on_cloud(label, cloud, merged)`` receives each view's clouds and, every ``merged_every``
    views and at the end, the merged clouds (``all`` only when there are several labels, since
    with one it repeats that label's).
    """

    def __init__(
        self,
        recon: Reconstructor,
        labels: LabelTable,
        truth: GroundTruth | None,
        thresholds_mm: list[float],
        on_cloud: CloudCallback | None = None,
        merged_every: int = 10,
    ) -> None:
        self.recon = recon
        self.labels = labels
        self.stats = ViewStats(truth)
        self.thresholds_mm = list(thresholds_mm)
        self.on_cloud = on_cloud
        self.merged_every = merged_every
        self._several = sum(lab.id != 0 for lab in labels.labels) > 1

    def add(self, view: View) -> None:
        """Integrate one view and count it."""
        self.stats.add(view)
        clouds = self.recon.integrate(view)
        if self.on_cloud is None:
            return
        for name, cloud in clouds.items():
            self.on_cloud(name, cloud, False)
        if self.stats.frames % self.merged_every == 0:
            self._announce_merged(self.recon.merged())

    def _announce_merged(self, clouds: dict[str, Cloud]) -> None:
        assert self.on_cloud is not None
        for name, cloud in clouds.items():
            if name != ALL or self._several:
                self.on_cloud(name, cloud, True)

    def finish(self, meta: dict[str, Any] | None = None) -> tuple[Reconstruction, dict[str, Any]]:
        """The final reconstruction and its metrics (``metrics.json``'s content)."""
        result = self.recon.result()
        # the last view may have announced the merge already: the same clouds, not twice
        if self.on_cloud is not None and self.stats.frames % self.merged_every != 0:
            final = dict(result.clouds)
            for name, mesh in result.meshes.items():
                final.setdefault(name, Cloud(mesh.vertices, _vertex_colors(mesh)))
            self._announce_merged(final)
        truth = self.stats.truth
        metrics: dict[str, Any] = dict(meta or {})
        if result.metrics:
            metrics[str(metrics.get("recon", "recon"))] = result.metrics
        metrics.update(
            {
                "frames": self.stats.frames,
                "thresholds_mm": self.thresholds_mm,
                "truth": None
                if truth is None
                else {
                    "samples": int(len(truth.points)),
                    "opaque_area_m2": None if truth.area_m2 is None else round(truth.area_m2, 6),
                    "surface": truth.mesh is not None,
                },
                "labels": evaluate(result, self.labels, self.stats, self.thresholds_mm),
                "leaf_instances_seen": self.stats.leaf_instances_seen,
            }
        )
        return result, metrics


def _vertex_colors(mesh: SurfaceMesh) -> np.ndarray:
    return mesh.colors if mesh.colors is not None else np.full((len(mesh.vertices), 3), 200, np.uint8)


def summary_metrics(metrics: dict[str, Any]) -> dict[str, Any]:
    """The headline numbers of ``metrics.json`` for ``run.json``'s summary: per label, points
    and precision/recall/F-score at each threshold."""
    out = {}
    for name, row in metrics.get("labels", {}).items():
        out[name] = {k: row[k] for k in ("pixels", "points", "precision", "recall", "fscore", "chamfer_mm") if k in row}
    return out


# ------------------------------------------------------------------------------ files


def metrics_meta(config: RunConfig) -> dict[str, Any]:
    """What a run's metrics.json says of the run it measures: the plant, the labels, the
    reconstructor, the depth it read, the seed."""
    return {
        "plant": config.plant,
        "seg_mode": config.render.seg_mode,
        "labels_mode": config.render.labels,
        "recon": config.recon.backend,
        "depth": depth_read(config),
        "seed": config.seed,
    }


def output_files(out_dir: Path, result: Reconstruction) -> list[Path]:
    """The files :func:`write_reconstruction` writes for ``result``."""
    return (
        [layout.cloud(out_dir, name) for name in result.clouds]
        + [layout.surface(out_dir, name) for name in result.meshes]
        + [out_dir / layout.METRICS_JSON]
    )


def cloud_ply(cloud: Cloud) -> bytes:
    """A cloud as binary PLY (float64 x, y, z and uchar red, green, blue): the very bytes
    Open3D's ``write_point_cloud`` writes, without needing Open3D (a GPU machine's minimal
    install writes clouds too)."""
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment Created by Open3D\n"
        f"element vertex {len(cloud.points)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    rows = np.empty(len(cloud.points), [("xyz", "<f8", 3), ("rgb", "u1", 3)])
    rows["xyz"], rows["rgb"] = cloud.points, cloud.colors
    return header.encode() + rows.tobytes()


def write_reconstruction(out_dir: Path, result: Reconstruction, metrics: dict[str, Any]) -> None:
    """``clouds/<label>.ply`` (binary PLY, colours), ``clouds/<label>_mesh.ply``, the
    reconstructor's own files and ``metrics.json``, each written atomically."""
    (out_dir / layout.CLOUDS).mkdir(parents=True, exist_ok=True)
    for name, cloud in result.clouds.items():
        # (an empty cloud too: Open3D refuses to write one, readers accept it)
        write_bytes(layout.cloud(out_dir, name), cloud_ply(cloud) if len(cloud.points) else _EMPTY_PLY)
    for relative, data in result.files.items():
        write_bytes(out_dir / relative, data)
    # a replaced reconstructor folder keeps nothing of the old result (e.g. another split's views)
    written = {out_dir / relative for relative in result.files}
    for folder in {Path(relative).parts[0] for relative in result.files}:
        for stale in [p for p in (out_dir / folder).rglob("*") if p.is_file() and p not in written]:
            stale.unlink()
    if result.meshes:
        import open3d as o3d
    for name, mesh in result.meshes.items():
        if len(mesh.vertices) == 0:
            write_bytes(layout.surface(out_dir, name), _EMPTY_PLY)
            continue
        tm = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(mesh.vertices), o3d.utility.Vector3iVector(mesh.triangles)
        )
        tm.vertex_colors = o3d.utility.Vector3dVector(_vertex_colors(mesh).astype(np.float64) / 255.0)

        def write(tmp: str, g: o3d.geometry.TriangleMesh = tm) -> bool:
            # Open3D's stub asks for an os.PathLike; its binding takes a str as well
            return o3d.io.write_triangle_mesh(tmp, g, write_ascii=False)  # type: ignore[arg-type]

        write_through(layout.surface(out_dir, name), write)
    write_json(out_dir / layout.METRICS_JSON, metrics)


_EMPTY_PLY = (
    b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty double x\nproperty double y\n"
    b"property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
)


# -------------------------------------------------------------------- from a saved run


def truth_from_run(run_dir: Path, samples: int, seed: int = 0, registry: Registry | None = None) -> GroundTruth | None:
    """The ground truth of a saved run: its ``scene/plant.glb`` (world coordinates), or for a
    scanned point plant its ``scene/plant_points.ply``, read by the installed readers of those
    formats (``registry``'s; default: every installed plugin's)."""
    from agrisim.config import PlantFileConfig
    from agrisim.registry import make_plugin_manager
    from agrisim.scene.plant_choice import reader_for

    if registry is None:
        from agrisim.registry import Registry

        registry = Registry(make_plugin_manager())
    for path, settings in (
        (run_dir / layout.PLANT_GLB, PlantFileConfig()),
        (run_dir / layout.PLANT_POINTS, PlantFileConfig(up="z")),
    ):
        if not path.is_file():
            continue
        reader = reader_for(registry, path)
        if reader is None:
            raise UserError(f"{path}: no installed plant-file reader reads it (see agrisim plugins)")
        plant = reader.read(path, settings, place=False)
        if plant.points is not None and not len(plant.mesh.faces):
            return GroundTruth.of_points(plant.points, samples, seed)
        return GroundTruth.sample(plant.mesh, samples, seed)
    return None


def capture_order(run: dict[str, Any], frames: Iterable[str]) -> list[str]:
    """``frames`` in the order they were captured: as run.json's results list them, then any
    others by name."""
    wanted = set(frames)
    order = [r["frame"] for r in run.get("results", []) if r.get("frame") in wanted]
    return order + sorted(wanted - set(order))


def rebuild(
    run_dir: Path,
    recon: Reconstructor,
    labels: LabelTable,
    run: dict[str, Any],
    cameras: dict[str, Any],
    truth: GroundTruth | None,
    thresholds_mm: list[float],
    progress: Callable[[int, int], None] | None = None,
    poses: dict[str, np.ndarray] | None = None,
    depth: str = "truth",
) -> ReconSession:
    """Feed every complete frame of a saved run, in capture order, to a fresh session; with
    ``poses`` (estimated ones, by frame) only those frames, at those poses; with the depth
    ``depth`` names (``truth``, or ``sensor``: what the run's depth sensor measured)."""
    session = ReconSession(recon, labels, truth, thresholds_mm)
    camera = camera_from_json(cameras["intrinsics"])
    frames = cameras["frames"]
    if poses is None:
        poses = {name: np.asarray(frame["world_T_camera"], float) for name, frame in frames.items()}
    order = [name for name in capture_order(run, frames) if name in poses]
    for i, name in enumerate(order):
        session.add(load_view(run_dir, name, camera, poses[name], depth))
        if progress:
            progress(i + 1, len(order))
    return session


def check_writable(out_dir: Path, labels: LabelTable, overwrite: bool, folder: str | None = None) -> None:
    """Refuse, before any work, to replace a reconstruction's outputs (and the reconstructor's
    own ``folder``) unless ``overwrite``."""
    names = [lab.name for lab in labels.labels if lab.id != 0] + [ALL]
    candidates = [out_dir / layout.METRICS_JSON] + [
        path for name in names for path in (layout.cloud(out_dir, name), layout.surface(out_dir, name))
    ]
    if folder is not None:
        candidates.insert(0, out_dir / folder)
    existing = [p for p in candidates if p.exists()]
    if existing and not overwrite:
        raise OutputError(
            f"{existing[0]} already exists; pass --overwrite to replace it or --out DIR to write elsewhere"
        )


__all__ = ["ReconSession", "rebuild", "read_run", "write_reconstruction", "summary_metrics", "check_writable"]


def reconstruct_saved_run(
    run_dir: Path,
    overrides: dict[str, Any],
    out_dir: Path | None = None,
    overwrite: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[Path, dict[str, Any]]:
    """``agrisim recon``: rebuild a complete run's reconstruction from its files.

    ``overrides`` may set ``recon`` (backend and its options) and ``metrics``; everything else
    is the run's saved configuration. Writes into ``out_dir`` (default: the run directory) and
    returns it with the metrics. Every input is checked before any work or write.
    """
    from agrisim.config import backend_options, build_config
    from agrisim.registry import Registry, blame, make_plugin_manager
    from agrisim.validation import pose_source

    unknown = set(overrides) - {"recon", "metrics"}
    if unknown:
        raise UserError(f"agrisim recon takes only recon.* and metrics.* settings, not {', '.join(sorted(unknown))}")
    run, cameras = read_run(run_dir)
    saved = run.get("config")
    if not isinstance(saved, dict):
        raise UserError(f"{run_dir / 'run.json'} holds no run configuration")
    saved = {k: v for k, v in saved.items() if k != "output"}
    config = build_config(saved, overrides)
    if config.recon.backend == "none":
        raise UserError("--recon none reconstructs nothing; choose a reconstructor (see agrisim plugins)")
    registry = Registry(make_plugin_manager())
    spec = registry.get("reconstructor", config.recon.backend)
    config.recon.check_tables("recon", registry.specs("reconstructor"))
    source = pose_source(registry, config.recon.poses) if config.recon.poses != "truth" else None
    options = backend_options(spec.options_model, config.recon.options_for(spec.name), f"reconstructor {spec.name!r}")
    lens = cameras["intrinsics"].get("distortion") is not None
    check_reconstructor(spec, config.render.hide_robots, lens=lens)
    if spec.preflight is not None:
        spec.preflight(config, options)
    labels = LabelTable.from_json(run["labels"])
    out = out_dir if out_dir is not None else run_dir
    check_writable(out, labels, overwrite, getattr(spec.capabilities, "folder", None))
    # Accuracy against the true surface needs Open3D (Embree's closest points); a GPU machine's
    # minimal install reconstructs without it and says so in metrics.json.
    measurable = importlib.util.find_spec("open3d") is not None
    truth = truth_from_run(run_dir, config.metrics.truth_samples, registry=registry) if measurable else None
    estimated = None
    if source is not None:
        with blame("poses", source, f" reading {run_dir}"):
            estimated = registry.build("poses", source, source.options_model()).poses(run_dir)
    session = rebuild(
        run_dir,
        registry.build("reconstructor", spec, labels, options),
        labels,
        run,
        cameras,
        truth,
        config.metrics.thresholds_mm,
        progress,
        estimated,
        config.recon.depth,
    )
    meta = {
        "plant": config.plant,
        "seg_mode": config.render.seg_mode,
        "labels_mode": config.render.labels,
        "recon": spec.name,
        "seed": config.seed,
        "source": str(run_dir),
        "poses": config.recon.poses,
        "depth": depth_read(config),
    }
    if not measurable:
        meta["truth_note"] = "accuracy not measured: Open3D is not installed here"
    result, metrics = session.finish(meta)
    write_reconstruction(out, result, metrics)
    return out, metrics
