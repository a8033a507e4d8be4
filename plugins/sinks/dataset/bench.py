"""A bench's plants as the run directory records them, so that readers and tools know the plants
without growing them again: ``run.json``'s ``bench`` and the scene GLB's (which adds each plant's
faces of the joined plant mesh), read back by the exports (COCO, nerfstudio, the ROS 2 bag) and
``agrisim render``.

One row a plant, in bench order: ``{"id": 1, "name": "plant_01", "plant": "indian_cress",
"seed": 7, "x": -0.25, "y": 0.0}``; ``id`` is the plant's value in ``plants/<frame>.png``
(its place in the list plus one), ``plant`` what grew it (a species or a file), ``x`` and ``y``
where its pot stands from the bench's centre (m). A run of one plant has no ``bench`` at all.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from agrisim.errors import UserError
from agrisim.scene.model import BenchPlant

#: run.json's (and the scene GLB's) key
KEY = "bench"


def bench_rows(plants: Sequence[BenchPlant], faces: bool = False) -> list[dict[str, Any]]:
    """The rows of ``plants`` (with each plant's ``faces`` range when ``faces``: the scene GLB's)."""
    return [
        {
            "id": k + 1,
            "name": p.name,
            "plant": p.plant,
            "seed": p.seed,
            "x": float(p.xy[0]),
            "y": float(p.xy[1]),
            **({"faces": [int(p.faces[0]), int(p.faces[1])]} if faces else {}),
        }
        for k, p in enumerate(plants)
    ]


def read_bench(doc: dict[str, Any], where: Path | str, error: type[UserError] = UserError) -> list[BenchPlant]:
    """The bench that ``doc`` (run.json, or the scene GLB's agrisim extras) records, checked;
    empty for one plant. A malformed record raises ``error`` naming ``where``."""
    rows = doc.get(KEY)
    if rows is None:
        return []
    try:
        if not isinstance(rows, list) or not rows:
            raise ValueError("not a list of plants")
        plants = []
        for k, row in enumerate(rows):
            xy = (float(row["x"]), float(row["y"]))
            faces = tuple(int(f) for f in row.get("faces", (0, 0)))
            if row["id"] != k + 1 or not all(math.isfinite(v) for v in xy) or len(faces) != 2:
                raise ValueError(f"plant {k + 1} is {row}")
            if type(row["seed"]) is not int or not isinstance(row["name"], str) or not isinstance(row["plant"], str):
                raise ValueError(f"plant {k + 1} is {row}")
            plants.append(BenchPlant(row["name"], row["plant"], row["seed"], xy, (faces[0], faces[1])))
    except (KeyError, TypeError, ValueError) as exc:
        raise error(f"{where}: malformed {KEY} ({exc})") from None
    return plants
