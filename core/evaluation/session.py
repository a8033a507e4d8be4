"""Reconstruction of a run, during the run or afterwards from its dataset on disk.

:class:`ReconSession` feeds views to a reconstructor backend, counts what the metrics need, and
passes per-view and merged clouds on (to the ``agrisim_cloud`` hook in a run). The episode uses
it view by view; ``agrisim recon RUN_DIR`` replays a saved dataset through the same session;
the dataset sink writes ``clouds/`` and ``metrics.json``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from agrisim.config import depth_read
from agrisim.evaluation.metrics import GroundTruth, ViewStats, evaluate
from agrisim.evaluation.views import View
from agrisim.interfaces import ALL, Cloud, Reconstruction, Reconstructor, SurfaceMesh
from agrisim.scene.model import LabelTable

if TYPE_CHECKING:
    from agrisim.config import RunConfig

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
                final.setdefault(name, Cloud(mesh.vertices, vertex_colors(mesh)))
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


def vertex_colors(mesh: SurfaceMesh) -> np.ndarray:
    """A reconstructed mesh's vertex colours (uint8 RGB), a light grey where it has none."""
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


__all__ = ["ReconSession", "metrics_meta", "summary_metrics", "vertex_colors"]
