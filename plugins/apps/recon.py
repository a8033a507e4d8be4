"""``agrisim recon RUN``: a finished run's reconstruction and metrics made again from its files,
with other reconstructor settings or on a pose source's poses (:func:`reconstruct_saved_run`),
its truth read back from the run's saved plant (:func:`truth_from_run`)."""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.capabilities import check_reconstructor
from agrisim.config import depth_read
from agrisim.errors import OutputError, UserError
from agrisim.evaluation.metrics import GroundTruth
from agrisim.evaluation.session import ReconSession
from agrisim.evaluation.views import load_view
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json, capture_order, read_run
from agrisim.interfaces import ALL, Reconstructor
from agrisim.plugins.sinks.dataset.bench import read_bench
from agrisim.plugins.sinks.dataset.plants import PLANTS_KEY, evaluate_plants, plant_files, write_plants
from agrisim.plugins.sinks.dataset.reconstruction import write_reconstruction
from agrisim.registry import Registry
from agrisim.scene.model import BenchPlant, LabelTable


def truth_from_run(run_dir: Path, samples: int, seed: int = 0, registry: Registry | None = None) -> GroundTruth | None:
    """The ground truth of a saved run: its ``scene/plant.glb`` (world coordinates), or for a
    scanned point plant its ``scene/plant_points.ply``, read by the installed readers of those
    formats (``registry``'s; default: every installed plugin's)."""
    from agrisim.config import PlantFileConfig
    from agrisim.plant_choice import reader_for
    from agrisim.registry import make_plugin_manager

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


def check_writable(
    out_dir: Path, labels: LabelTable, overwrite: bool, folder: str | None = None, bench: list[BenchPlant] | None = None
) -> None:
    """Refuse, before any work, to replace a reconstruction's outputs (and the reconstructor's
    own ``folder``, and a ``bench``'s plants' clouds) unless ``overwrite``."""
    names = [lab.name for lab in labels.labels if lab.id != 0] + [ALL]
    candidates = [out_dir / layout.METRICS_JSON] + [
        path for name in names for path in (layout.cloud(out_dir, name), layout.surface(out_dir, name))
    ]
    candidates += plant_files(out_dir, bench or [])
    if folder is not None:
        candidates.insert(0, out_dir / folder)
    existing = [p for p in candidates if p.exists()]
    if existing and not overwrite:
        raise OutputError(
            f"{existing[0]} already exists; pass --overwrite to replace it or --out DIR to write elsewhere"
        )


__all__ = ["check_writable", "rebuild", "reconstruct_saved_run", "truth_from_run"]


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
    bench = read_bench(run, run_dir / layout.RUN_JSON)
    check_writable(out, labels, overwrite, getattr(spec.capabilities, "folder", None), bench)
    # Accuracy against the true surface needs Open3D (Embree's closest points); a GPU machine's
    # minimal install reconstructs without it and says so in metrics.json.
    measurable = importlib.util.find_spec("open3d") is not None
    truth = truth_from_run(run_dir, config.metrics.truth_samples, registry=registry) if measurable else None
    estimated = None
    if source is not None:
        with blame("poses", source, f" reading {run_dir}"):
            estimated = registry.build("poses", source, source.options_model()).poses(run_dir)

    def make() -> Reconstructor:
        return registry.build("reconstructor", spec, labels, options)

    session = rebuild(
        run_dir,
        make(),
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
    if bench:  # each plant alone, as the run did it (the same function, the same files)
        samples = config.metrics.truth_samples if measurable else None
        plants = evaluate_plants(
            run_dir,
            bench,
            make,
            labels,
            run,
            cameras,
            config.metrics.thresholds_mm,
            samples,
            registry,
            depth=config.recon.depth,
            poses=estimated,
        )
        metrics[PLANTS_KEY] = write_plants(out, plants)
    write_reconstruction(out, result, metrics)
    return out, metrics
