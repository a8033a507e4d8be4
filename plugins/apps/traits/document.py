"""``traits.json``: a plant's traits as ``agrisim traits`` writes them, with their units and
where they are defined (docs/traits.md, field by field)."""

from __future__ import annotations

from typing import Any

from agrisim.plugins.apps.traits.estimate import PlantEstimate
from agrisim.plugins.apps.traits.scores import trait_errors
from agrisim.plugins.apps.traits.truth import INCLINATION_BINS, PROJECTION_CELL_M, PlantTraits
from agrisim.scene.model import Plant
from agrisim.version import __version__

#: the units of traits.json's fields, by the suffix of their names
UNITS = {"_m": "metres", "_m2": "square metres", "_m3": "cubic metres", "_deg": "degrees", "shares": "area shares"}


def traits_document(
    plant: Plant, seed: int, truth: PlantTraits, measured: PlantEstimate | None = None
) -> dict[str, Any]:
    """The traits.json document of ``plant`` (grown with ``seed``): its ``truth``, and where
    given what was ``measured`` of it from a run's views with its errors against the truth."""
    traits = truth.to_json()
    leaves = traits.pop("leaves")
    doc = {
        "agrisim": __version__,
        "plant": {"name": plant.name, "seed": seed, **traits},
        "leaves": leaves,
        "frame": "the plant's: z up from the soil, the stem at x = y = 0",
        "units": UNITS,
        "inclination_bins_deg": INCLINATION_BINS.tolist(),
        "projection_cell_m": PROJECTION_CELL_M,
        "definitions": "docs/traits.md",
    }
    if measured is not None:
        doc["measured"] = {**measured.to_json(), "errors": trait_errors(truth, measured).to_json()}
    return doc
