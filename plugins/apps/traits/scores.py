"""How far a plant's estimated traits (:mod:`agrisim.plugins.apps.traits.estimate`) lie from its truth
(:mod:`agrisim.plugins.apps.traits.truth`), as phenotyping studies report it: leaves found against leaves
there, the per-leaf area's mean absolute percentage error over the leaves seen, the leaf
inclination's error in degrees, and the plant's height and hull. Leaves meet by id."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from agrisim.plugins.apps.traits.estimate import PlantEstimate
from agrisim.plugins.apps.traits.truth import PlantTraits


@dataclass
class TraitErrors:
    """Estimate against truth; percentages are of the true value, signed ones estimate - truth."""

    leaves_there: int
    leaves_seen: int
    clusters: int
    clusters_one_leaf: int
    area_mape_pct: float
    area_error_min_pct: float
    area_error_max_pct: float
    inclination_error_mean_deg: float
    inclination_error_max_deg: float
    height_error_m: float
    hull_volume_error_pct: float

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def trait_errors(truth: PlantTraits, estimate: PlantEstimate) -> TraitErrors:
    """The errors of ``estimate`` against ``truth`` (see the module); a leaf estimated with no
    true leaf of its id is ignored, a true leaf never seen counts only in ``leaves_seen``."""
    true_leaf = {leaf.id: leaf for leaf in truth.leaves}
    pairs = [(true_leaf[e.id], e) for e in estimate.leaves if e.id in true_leaf and true_leaf[e.id].area_m2 > 0]
    area = np.array([100.0 * (e.area_m2 / t.area_m2 - 1.0) for t, e in pairs])
    incline = np.array([abs(e.inclination_deg - t.inclination_deg) for t, e in pairs])
    hull = truth.convex_hull_volume_m3
    return TraitErrors(
        leaves_there=truth.leaf_count,
        leaves_seen=len(pairs),
        clusters=estimate.clusters.count,
        clusters_one_leaf=estimate.clusters.one_leaf,
        area_mape_pct=float(np.abs(area).mean()) if len(area) else float("nan"),
        area_error_min_pct=float(area.min()) if len(area) else float("nan"),
        area_error_max_pct=float(area.max()) if len(area) else float("nan"),
        inclination_error_mean_deg=float(incline.mean()) if len(incline) else float("nan"),
        inclination_error_max_deg=float(incline.max()) if len(incline) else float("nan"),
        height_error_m=estimate.height_m - truth.height_m,
        hull_volume_error_pct=100.0 * (estimate.convex_hull_volume_m3 / hull - 1.0) if hull > 0 else float("nan"),
    )
