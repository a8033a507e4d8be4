"""A bench's plants each reconstructed and measured on its own (issue 62): plant k's views are
its pixels only (``Frame.plants == k``: labels, depth and instances cleared elsewhere, so a
neighbour in front of it hides what it hides and adds nothing), its truth only its own faces of
the saved plant (``scene/plant.glb``, the range run.json's ``bench`` gives it). Each plant's
clouds go to ``clouds/<plant>/`` and its metrics to ``metrics.json``'s ``plants``, in the same
form as the whole run's.

A run (the dataset sink, at its end) and ``agrisim recon`` both replay the frames from disk
through :func:`evaluate_plants`, so the two write the same per-plant files. A view that does
not show a plant is not given to that plant's reconstruction (``frames`` counts those that do).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import UserError
from agrisim.evaluation.metrics import GroundTruth
from agrisim.evaluation.session import ReconSession
from agrisim.evaluation.views import load_view
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json, capture_order
from agrisim.interfaces import Reconstruction, Reconstructor, View
from agrisim.plugins.sinks.dataset.reconstruction import write_clouds
from agrisim.registry import Registry
from agrisim.scene.model import BenchPlant, LabelTable, Mesh

#: metrics.json's key for each plant's metrics (present only on a bench)
PLANTS_KEY = "plants"


def plant_view(view: View, plant_id: int) -> View | None:
    """``view`` with only the pixels of the bench's plant ``plant_id`` (labels, depth, the
    sensor's depth and leaf instances cleared elsewhere); None where it does not show it."""
    images = view.images
    if images.plants is None:
        raise UserError(f"frame {view.frame} has no plants/ mask: the run's renderer did not tell the plants apart")
    mine = images.plants == plant_id
    if not mine.any():
        return None

    def only(image: np.ndarray) -> np.ndarray:
        return np.where(mine, image, np.zeros((), image.dtype))

    masked = dataclasses.replace(
        images,
        labels=only(images.labels),
        depth=only(images.depth),
        instances=None if images.instances is None else only(images.instances),
        depth_sensor=None if images.depth_sensor is None else only(images.depth_sensor),
    )
    return dataclasses.replace(view, images=masked)


def plant_surface(mesh: Mesh, faces: tuple[int, int]) -> Mesh:
    """The faces ``range(*faces)`` of ``mesh`` as a mesh of their own (only the vertices they
    use, in their order)."""
    a, b = faces
    if not 0 <= a <= b <= len(mesh.faces):
        raise UserError(f"bench: faces {a}..{b} are not within the saved plant's {len(mesh.faces)}")
    used, remapped = np.unique(mesh.faces[a:b], return_inverse=True)
    pick = None if mesh.face_instance is None else mesh.face_instance[a:b]
    return Mesh(
        mesh.name,
        mesh.vertices[used],
        remapped.reshape(-1, 3),
        mesh.materials,
        mesh.face_material[a:b],
        None if mesh.uvs is None else mesh.uvs[used],
        pick,
        None if mesh.colors is None else mesh.colors[used],
    )


def saved_surface(run_dir: Path, registry: Registry) -> Mesh:
    """The bench's true surface as the run saved it (``scene/plant.glb``, world coordinates),
    read by the installed reader of glTF."""
    from agrisim.config import PlantFileConfig
    from agrisim.plant_choice import reader_for

    path = run_dir / layout.PLANT_GLB
    reader = reader_for(registry, path) if path.is_file() else None
    if reader is None:
        raise UserError(f"{path}: missing, or no installed plant-file reader reads it (see agrisim plugins)")
    return reader.read(path, PlantFileConfig(), place=False).mesh


def evaluate_plants(
    run_dir: Path,
    bench: list[BenchPlant],
    make: Callable[[], Reconstructor],
    labels: LabelTable,
    run: dict[str, Any],
    cameras: dict[str, Any],
    thresholds_mm: list[float],
    truth_samples: int | None,
    registry: Registry,
    *,
    depth: str = "truth",
    poses: dict[str, np.ndarray] | None = None,
) -> dict[str, tuple[Reconstruction, dict[str, Any]]]:
    """Each plant of ``bench`` reconstructed (a fresh reconstructor of ``make``'s) from its own
    pixels of every complete frame of the run in ``run_dir``, in capture order (with ``poses``:
    only those frames, at those poses; depth as ``depth`` names), and measured against its own
    faces of the saved plant sampled ``truth_samples`` times (None: not measured). By plant
    name: its reconstruction and its metrics (:meth:`ReconSession.finish`'s, with what grew it
    and where it stands)."""
    surface = saved_surface(run_dir, registry) if truth_samples is not None else None
    sessions = []
    for slot in bench:
        truth = None
        if surface is not None and truth_samples is not None:
            truth = GroundTruth.sample(plant_surface(surface, slot.faces), truth_samples)
        sessions.append(ReconSession(make(), labels, truth, thresholds_mm))
    camera = camera_from_json(cameras["intrinsics"])
    frames = cameras["frames"]
    if poses is None:
        poses = {name: np.asarray(frame["world_T_camera"], float) for name, frame in frames.items()}
    for name in [name for name in capture_order(run, frames) if name in poses]:
        view = load_view(run_dir, name, camera, poses[name], depth)
        for k, session in enumerate(sessions, 1):
            mine = plant_view(view, k)
            if mine is not None:
                session.add(mine)
    return {
        slot.name: session.finish({"plant": slot.plant, "seed": slot.seed, "xy": list(slot.xy)})
        for slot, session in zip(bench, sessions, strict=True)
    }


def write_plants(out_dir: Path, plants: dict[str, tuple[Reconstruction, dict[str, Any]]]) -> dict[str, Any]:
    """Each plant's clouds and surfaces in ``clouds/<plant>/``; returns metrics.json's
    ``plants`` (each plant's metrics by name)."""
    for name, (result, _) in plants.items():
        write_clouds(out_dir, result, name)
    return {name: metrics for name, (_, metrics) in plants.items()}


def plant_files(out_dir: Path, bench: list[BenchPlant]) -> list[Path]:
    """The folders of the bench's plants' clouds (``clouds/<plant>/``)."""
    return [out_dir / layout.CLOUDS / slot.name for slot in bench]


def run_reconstructor(registry: Registry, config: Any, labels: LabelTable) -> Callable[[], Reconstructor]:
    """What builds a fresh reconstructor of a run's (``config.recon``), as ``agrisim recon``
    builds it."""
    from agrisim.config import backend_options

    spec = registry.get("reconstructor", config.recon.backend)
    options = backend_options(spec.options_model, config.recon.options_for(spec.name), f"reconstructor {spec.name!r}")
    return lambda: registry.build("reconstructor", spec, labels, options)
