"""Point-cloud plants in: PLY (without faces) and PCD files as :class:`Plant` s drawn as points,
agrisim's own PLY of a cloud (``scene/plant_points.ply``, :mod:`agrisim.plugins.sinks.dataset.point_cloud`) among
them.

Properties read (per point; names as PCL, CloudCompare and Open3D write them)
----------------------------------------------------------------------------
* ``x y z``: position (any numeric type; read in float64 from PLY).
* colour: PLY ``red green blue`` (uint8, uint16 scaled by 1/257, or floats in 0..1); PCD
  ``rgb``/``rgba`` (packed, as PCL writes it). Without colours every point is leaf green.
* ``label``: label id 0..255 (any integer type); without it every point is label 1 ("plant").
  Label 0 is drawn but not plant (soil, a stake).
* ``instance``: leaf instance id 0..65535 (0: none), drawn into the instance images.

Frames: scans have no up-axis convention of their own; agrisim reads them z-up (PCL, ROS, LAS),
and ``[plant_file] up = "y"`` reads a y-up cloud (as glTF is) with the same rotation as meshes.
Then, as meshes, ``scale`` multiplies the coordinates and the cloud is placed in the plant
frame (lowest point at z = 0, bounding box centred on x = y = 0).

Label table (first that applies): ``[plant_file] label_names`` (``{"1" = "leaf", "2" =
"stem"}``); the table in an agrisim PLY's header (``comment agrisim {json}``); else the default
table of a plant without organ labels, 0 "background" and 1 "plant", as for meshes. A point whose
label the table does not name is refused (a scan's other ids need their names: a guessed
``label_<id>`` would reach the dataset's label table unnoticed).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np

from agrisim.plugins.formats.asset_reading import (
    AssetError,
    check_scale,
    open_asset,
    plant_frame_offset,
    unit_hint,
    y_up_to_z_up,
)
from agrisim.plugins.sinks.dataset.point_cloud import PLY_COMMENT
from agrisim.scene.model import Label, LabelTable, Mesh, Plant, PointSet
from agrisim.scene.palette import BACKGROUND, PALETTE

__all__ = ["POINT_FORMATS", "load_point_plant"]

POINT_FORMATS = (".ply", ".pcd")
"""File suffixes :func:`load_point_plant` reads."""

#: colour of points a file gives none (a mid leaf green, sRGB)
DEFAULT_COLOR = (70, 120, 40)


def _header_comment(real: Path) -> dict[str, Any] | None:
    """The JSON of an agrisim PLY's ``comment agrisim {...}`` header line, if any."""
    with open(real, "rb") as f:
        head = f.read(64 * 1024)
    end = head.find(b"end_header")
    for raw in head[: end if end >= 0 else len(head)].split(b"\n"):
        line = raw.decode("latin-1").strip()
        if line.startswith(f"comment {PLY_COMMENT} "):
            try:
                doc = json.loads(line[len(f"comment {PLY_COMMENT} ") :])
            except json.JSONDecodeError:
                return None
            return doc if isinstance(doc, dict) else None
    return None


def _read_ply(real: Path, shown: str) -> dict[str, np.ndarray]:
    import trimesh

    try:
        loaded = trimesh.load(str(real), file_type="ply", process=False)
    except KeyError as exc:  # trimesh assumes x, y, z
        raise AssetError(f"{shown}: points need x, y and z properties (missing {exc})") from None
    except Exception as exc:  # trimesh raises many kinds on malformed files
        raise AssetError(f"{shown}: not a readable PLY file ({type(exc).__name__}: {exc})") from None
    faces = getattr(loaded, "faces", None)
    if faces is not None and len(faces):
        raise AssetError(
            f"{shown}: a PLY with {len(faces):,} faces is a mesh; agrisim reads PLY as point clouds "
            "(give meshes as .glb, .gltf or .obj)"
        )
    raw = loaded.metadata.get("_ply_raw", {}).get("vertex", {}).get("data")
    if isinstance(raw, np.ndarray) and raw.dtype.names:  # binary files: one structured array
        raw = {name: raw[name] for name in raw.dtype.names}
    if not isinstance(raw, Mapping):
        if len(getattr(loaded, "vertices", ())) == 0:
            raise AssetError(f"{shown}: the file holds no points")
        raise AssetError(f"{shown}: no vertex element (x, y, z) in this PLY")
    return {
        str(k): np.asarray(v).reshape(len(v), -1)[:, 0] if np.asarray(v).ndim > 1 else np.asarray(v)
        for k, v in raw.items()
    }


def _read_pcd(real: Path, shown: str) -> dict[str, np.ndarray]:
    from agrisim.plugins.native_output import native_output_silenced

    with native_output_silenced():
        import open3d as o3d

        # Open3D's stub asks for an os.PathLike; its binding takes a str as well
        cloud = o3d.t.io.read_point_cloud(str(real))  # type: ignore[arg-type]
    out: dict[str, np.ndarray] = {}
    for key in cloud.point:
        value = cloud.point[key].numpy()
        if key == "positions":
            for j, axis in enumerate("xyz"):
                out[axis] = value[:, j].astype(np.float64)
        elif key == "colors":
            for j, c in enumerate(("red", "green", "blue")):
                out[c] = value[:, j]
        else:
            out[key] = value.reshape(len(value), -1)[:, 0]
    if "x" not in out:
        raise AssetError(f"{shown}: not a readable PCD file (no x, y, z fields)")
    return out


def _colors(props: Mapping[str, np.ndarray], shown: str, n: int) -> np.ndarray:
    names = next((c for c in (("red", "green", "blue"), ("r", "g", "b")) if all(k in props for k in c)), None)
    if names is None:
        return np.tile(np.asarray(DEFAULT_COLOR, np.uint8), (n, 1))
    rgb = np.column_stack([props[k] for k in names])
    if rgb.dtype == np.uint8:
        return np.ascontiguousarray(rgb)
    if np.issubdtype(rgb.dtype, np.integer):
        if rgb.min() < 0 or rgb.max() > 65535:
            raise AssetError(f"{shown}: colours must be 0..255 (uchar), 0..65535 (ushort) or 0..1 (float)")
        scale = 257.0 if rgb.max() > 255 else 1.0
        return np.round(rgb / scale).astype(np.uint8)
    rgb = rgb.astype(np.float64)
    if not np.all(np.isfinite(rgb)) or rgb.min() < 0 or rgb.max() > 1:
        raise AssetError(f"{shown}: float colours must lie within 0..1")
    return np.round(rgb * 255.0).astype(np.uint8)


def _ids(props: Mapping[str, np.ndarray], key: str, shown: str, top: int, dtype: type) -> np.ndarray | None:
    if key not in props:
        return None
    v = props[key]
    if not np.issubdtype(v.dtype, np.number):
        raise AssetError(f"{shown}: property {key!r} must be a number per point")
    if not np.issubdtype(v.dtype, np.integer):
        if not np.all(np.isfinite(v)) or np.any(v != np.round(v)):
            raise AssetError(f"{shown}: property {key!r} must hold whole numbers 0..{top}")
    bad = (v < 0) | (v > top)
    if bad.any():
        i = int(np.argmax(bad))
        raise AssetError(f"{shown}: {key} {v[i]!r} of point {i} is outside 0..{top} ({int(bad.sum())} such points)")
    return v.astype(dtype)


def _table(
    present: np.ndarray, names: Mapping[int | str, str] | None, embedded: list[Any] | None, shown: str
) -> LabelTable:
    """The label table of a cloud whose points carry the ids ``present`` (module doc)."""
    if names:
        labels = [Label(0, "background", BACKGROUND)]
        for k, name in names.items():
            try:
                i = int(k)
            except (TypeError, ValueError):
                raise AssetError(f"{shown}: label_names keys must be label ids 1..255, got {k!r}") from None
            if not 1 <= i <= 255:
                raise AssetError(f"{shown}: label_names keys must be label ids 1..255, got {k!r}")
            labels.append(Label(i, str(name), PALETTE.get(str(name), PALETTE["plant"])))
        table = LabelTable(sorted(labels, key=lambda lab: lab.id))
        source = "[plant_file] label_names"
    elif embedded is not None:
        try:
            table = LabelTable.from_json(embedded)
        except (KeyError, TypeError, ValueError) as exc:
            raise AssetError(f"{shown}: the label table in its header is malformed ({exc})") from None
        source = "the table in its header"
    else:
        table = LabelTable([Label(0, "background", BACKGROUND), Label(1, "plant", PALETTE["plant"])])
        source = "the default table (0 background, 1 plant)"
    known = {lab.id for lab in table.labels}
    unknown = [int(i) for i in present if int(i) not in known]
    if unknown:
        example = ", ".join(f'"{i}" = "leaf"' for i in unknown[:1])
        raise AssetError(
            f"{shown}: points carry label ids {unknown[:8]} that {source} does not name (it names "
            f"{sorted(known)}); name every id in [plant_file] label_names, e.g. {{{example}}}"
        )
    return table


def load_point_plant(
    path: str | os.PathLike[str],
    *,
    label_names: Mapping[int | str, str] | None = None,
    up: Literal["y", "z"] | None = None,
    scale: float = 1.0,
    root: str | os.PathLike[str] | None = None,
    name: str | None = None,
    max_size: float = 3.0,
    place: bool = True,
) -> Plant:
    """Read a point-cloud plant (``.ply`` without faces, ``.pcd``); module doc for what is read.

    The plant's ``points`` are the cloud in the plant frame (size unset, the run chooses it,
    unless the file is agrisim's and says it);
    its ``mesh`` has no faces. ``place=False`` keeps the file's frame (after ``up`` and
    ``scale``) instead of moving the cloud into the plant frame. Raises :class:`AssetError` (one line) for anything unreadable:
    no points, NaN or infinite coordinates, labels outside 0..255 or not in the table.
    """
    shown, _, real, suffix = open_asset(path, root, POINT_FORMATS, "point-cloud")
    check_scale(scale, shown)
    props = _read_ply(real, shown) if suffix == ".ply" else _read_pcd(real, shown)
    if not all(k in props for k in "xyz"):
        raise AssetError(f"{shown}: points need x, y and z properties; found {sorted(props)}")
    n = len(props["x"])
    if n == 0:
        raise AssetError(f"{shown}: the file holds no points")
    v = np.column_stack([props[k].astype(np.float64) for k in "xyz"])
    bad = ~np.all(np.isfinite(v), axis=1)
    if bad.any():
        raise AssetError(
            f"{shown}: {int(bad.sum()):,} of its {n:,} points have NaN or infinite coordinates (the first is point {int(np.argmax(bad))})"
        )
    if (up or "z") == "y":
        v = y_up_to_z_up(v)
    v = v * float(scale)
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float((hi - lo).max())
    if size > max_size:
        raise AssetError(
            f"{shown}: the cloud is {size:.4g} m across, more than {max_size:g} m{unit_hint(size, max_size)}"
        )
    if place:
        v = v - plant_frame_offset(lo, hi)
    labels = _ids(props, "label", shown, 255, np.uint8)
    if labels is None:
        labels = np.ones(n, np.uint8)
    instances = _ids(props, "instance", shown, 65535, np.uint16)
    header = _header_comment(real) if suffix == ".ply" else None
    table = _table(np.unique(labels), label_names, header.get("labels") if header else None, shown)
    drawn = header.get("size") if header else None
    if not (isinstance(drawn, (int, float)) and math.isfinite(drawn) and drawn > 0):
        drawn = None
    points = PointSet(
        v, _colors(props, shown, n), labels, instances, None if drawn is None else float(drawn) * float(scale)
    )
    plant_name = name or Path(path).stem
    empty = Mesh(plant_name, np.zeros((0, 3)), np.zeros((0, 3), np.int32), [], np.zeros(0, np.int32))
    organs = sum(1 for lab in table.labels if lab.id != 0) > 1
    return Plant(plant_name, empty, table, organs=organs, points=points)
