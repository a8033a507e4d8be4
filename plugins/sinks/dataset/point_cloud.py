"""The PLY agrisim writes of a cloud (``scene/plant_points.ply``): binary x y z, colours, labels
and leaf instances, with the label table and the drawn point size in a ``comment agrisim {json}``
header line, so that the point-cloud reader (:mod:`agrisim.plugins.formats.point_cloud`) reads
it back exactly."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.files.atomic import write_bytes
from agrisim.scene.model import LabelTable, PointSet

__all__ = ["PLY_COMMENT", "write_points_ply"]

#: the word that starts agrisim's own header comment (``comment agrisim {json}``)
PLY_COMMENT = "agrisim"


def write_points_ply(path: str | os.PathLike[str], points: PointSet, labels: LabelTable | None = None) -> None:
    """Write ``points`` as a binary PLY: x y z (double), red green blue, label, instance (when
    there are instances), with the label table and point size in a ``comment agrisim`` header
    line, so that the point-cloud reader reads it back exactly (as ``[plant_file]`` reads it:
    then placed in the plant frame)."""
    n = len(points)
    fields = [("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("label", "u1")]
    if points.instances is not None:
        fields.append(("instance", "<u2"))
    data = np.empty(n, dtype=np.dtype(fields))
    for j, axis in enumerate("xyz"):
        data[axis] = points.positions[:, j]
    for j, c in enumerate(("red", "green", "blue")):
        data[c] = points.colors[:, j]
    data["label"] = points.labels
    if points.instances is not None:
        data["instance"] = points.instances
    meta: dict[str, Any] = {"format": 1, "size": points.size}
    if labels is not None:
        meta["labels"] = labels.to_json()
    kinds = {"<f8": "double", "u1": "uchar", "<u2": "ushort"}
    header = ["ply", "format binary_little_endian 1.0", f"comment {PLY_COMMENT} {json.dumps(meta, separators=(',', ':'))}",
              f"element vertex {n}", *(f"property {kinds[t]} {name}" for name, t in fields), "end_header"]  # fmt: skip
    write_bytes(Path(path), ("\n".join(header) + "\n").encode("ascii") + data.tobytes())
