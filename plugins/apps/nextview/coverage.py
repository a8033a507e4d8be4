"""How much of the true plant surface the views so far have seen, from the ground truth's
samples (uniform by opaque area): a sample is seen by a view that sees it within its pixel's
depth and label (:func:`agrisim.evaluation.metrics.visible_samples`).

A leaf is a sheet with two sides, and a phenotyping view set should see both (the underside
carries the stomata, the veins' relief, the lesions): each side of a leaf sample is half of it,
seen by a view on that side of its triangle. Every other organ (stems, flowers, fruit) is a
closed surface seen from outside: its sample is whole once seen. A sample seen stays seen.
"""

from __future__ import annotations

import numpy as np

from agrisim.evaluation.metrics import GroundTruth, visible_samples
from agrisim.evaluation.views import View


class SurfaceCoverage:
    """The share of ``truth``'s surface seen by the views added so far (see the module)."""

    def __init__(self, truth: GroundTruth) -> None:
        self.truth = truth
        n = len(truth.points)
        self.sheet = np.zeros(n, bool) if truth.instances is None else truth.instances > 0
        # (front, back): a closed organ's sample has one side, counted as its front
        self.seen = np.zeros((n, 2), bool)

    @property
    def value(self) -> float:
        """The share of the surface seen, 0 to 1."""
        n = len(self.seen)
        if n == 0:
            return 0.0
        whole = self.seen[~self.sheet, 0].sum()
        halves = self.seen[self.sheet].sum()
        return float(whole + 0.5 * halves) / n

    def visible(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        """The samples ``view`` sees that are not yet fully seen, and the side it sees each
        from (0 front, 1 back; 0 for a closed organ's)."""
        idx = np.flatnonzero(~self.seen.all(axis=1) & (self.sheet | ~self.seen[:, 0]))
        seen = idx[visible_samples(self.truth, view, idx)]
        if self.truth.normals is None:
            return seen, np.zeros(len(seen), np.int64)
        towards = view.world_T_camera[:3, 3] - self.truth.points[seen]
        side = ((towards * self.truth.normals[seen]).sum(axis=1) < 0).astype(np.int64)
        side[~self.sheet[seen]] = 0
        return seen, side

    def gain(self, seen: np.ndarray, side: np.ndarray) -> float:
        """The share of the surface that samples ``seen`` from ``side`` would add."""
        new = ~self.seen[seen, side]
        return float(np.where(self.sheet[seen[new]], 0.5, 1.0).sum()) / max(len(self.seen), 1)

    def add(self, view: View) -> float:
        """Add ``view``; returns the share of the surface it saw first."""
        seen, side = self.visible(view)
        gained = self.gain(seen, side)
        self.seen[seen, side] = True
        return gained
