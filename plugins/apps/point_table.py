"""The paper's Table 3 from ``metrics.json`` documents: a plant as its mesh, then as points of
each size; rows, markdown, CSV and a chart.

Per row: labelled pixels and reconstructed points (the paper's columns), and what the paper
could not measure: precision and recall at a threshold and the Chamfer distance against the
plant's true surface, and the apparent thickness of its leaves in the reconstruction (the spread
of the points along the true surface normal, :func:`agrisim.evaluation.metrics.thickness_mm`).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from typing import Any

from agrisim.plugins.apps.table import TABLE_LABEL, plant_title, table_threshold

#: measures with one value per row
SCALARS = ("pixels", "points", "chamfer_mm", "thickness_mm")
#: measures with one value per threshold
PER_THRESHOLD = ("precision", "recall", "fscore")


def point_rows(
    metrics: Mapping[tuple[str, str], Mapping[str, Any] | None],
    plants: Sequence[str],
    variants: Sequence[str],
    as_points: int | None,
) -> list[dict[str, Any]]:
    """One row per plant and variant (``mesh``, then each point size in metres) from
    ``metrics[(plant, variant)]`` (a ``metrics.json`` or None); values None where a run is missing."""
    rows = []
    for plant in plants:
        for variant in variants:
            doc = metrics.get((plant, variant)) or {}
            entry = (doc.get("labels") or {}).get(TABLE_LABEL) or {}
            row: dict[str, Any] = {
                "plant": plant,
                "variant": variant,
                "size_m": None if variant == "mesh" else float(variant),
                "as_points": None if variant == "mesh" else as_points,
                "frames": doc.get("frames"),
            }
            for measure in SCALARS:
                row[measure] = entry.get(measure)
            for measure in PER_THRESHOLD:
                row[measure] = dict(entry.get(measure) or {})
            rows.append(row)
    return rows


def _thresholds(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The thresholds (mm, ``%g`` strings) the rows carry, in increasing order."""
    return sorted({k for r in rows for m in PER_THRESHOLD for k in r[m]}, key=float)


def _fmt(value: Any, spec: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return format(value, spec)


def _size(row: Mapping[str, Any]) -> str:
    """The size column: the mesh, or the diameter in mm with the paper's Unreal units beside it
    (1 uu = 1 cm, so the paper's size s is s cm: mm / 10)."""
    if row["size_m"] is None:
        return "mesh"
    mm = row["size_m"] * 1e3
    return f"{mm:g} mm ({mm / 10:g})"


def point_markdown(rows: Sequence[Mapping[str, Any]]) -> str:
    """Table 3 in markdown: per plant, the mesh then each size; pixels in 10^6 as the paper."""
    thr = table_threshold(_thresholds(rows))
    heads = ["Plant", "Size (paper's units)", "Pixels (10^6)", "Points"]
    if thr:
        heads += [f"Precision@{thr}mm", f"Recall@{thr}mm"]
    heads += ["Chamfer (mm)", "Thickness (mm)"]
    lines = ["| " + " | ".join(heads) + " |", "|" + "|".join(["---", "---"] + ["---:"] * (len(heads) - 2)) + "|"]
    for r in rows:
        cells = [plant_title(r["plant"]), _size(r)]
        cells += [_fmt(None if r["pixels"] is None else r["pixels"] / 1e6, ".3f"), _fmt(r["points"], ",d")]
        if thr:
            cells += [_fmt(r["precision"].get(thr), ".3f"), _fmt(r["recall"].get(thr), ".3f")]
        cells += [_fmt(r["chamfer_mm"], ".2f"), _fmt(r["thickness_mm"], ".2f")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def point_csv(rows: Sequence[Mapping[str, Any]]) -> str:
    """Table 3 as CSV: raw counts, every threshold, repr-exact floats; empty cells where missing."""
    thresholds = _thresholds(rows)
    cols = ["plant", "variant", "size_m", "as_points", "frames", *SCALARS]
    cols += [f"{m}_{t}mm" for m in PER_THRESHOLD for t in thresholds]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(cols)
    for r in rows:
        values: list[Any] = [r[c] for c in cols[: 5 + len(SCALARS)]]
        values += [r[m].get(t) for m in PER_THRESHOLD for t in thresholds]
        writer.writerow(["" if v is None else repr(v) if isinstance(v, float) else v for v in values])
    return buf.getvalue()


def point_chart_png(rows: Sequence[Mapping[str, Any]]) -> bytes:
    """Per plant, against the point size (log axis; the mesh as a dashed line): labelled
    pixels, reconstructed points, precision and recall, and the leaves' apparent thickness."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    thr = table_threshold(_thresholds(rows))
    plants = list(dict.fromkeys(r["plant"] for r in rows))
    panels = [("Labelled pixels (10^6)", lambda r: None if r["pixels"] is None else r["pixels"] / 1e6),
              ("Points in the merged cloud (10^3)", lambda r: None if r["points"] is None else r["points"] / 1e3)]  # fmt: skip
    if thr:
        panels += [(f"Precision at {thr} mm", lambda r: r["precision"].get(thr)),
                   (f"Recall at {thr} mm", lambda r: r["recall"].get(thr))]  # fmt: skip
    panels += [("Apparent leaf thickness (mm)", lambda r: r["thickness_mm"])]
    ncols = 3 if len(panels) > 4 else 2
    nrows = math.ceil(len(panels) / ncols)
    fig = Figure(figsize=(4.2 * ncols, 3.2 * nrows + 0.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(panels) :]:
        ax.set_visible(False)
    colours = ["#3a923a", "#d1495b", "#2e86ab", "#edae49", "#66462c"]
    for ax, (title, get) in zip(axes, panels, strict=False):  # the grid may have an axis spare
        for k, plant in enumerate(plants):
            colour = colours[k % len(colours)]
            mine = [r for r in rows if r["plant"] == plant]
            pts = [(r["size_m"] * 1e3, get(r)) for r in mine if r["size_m"] is not None and get(r) is not None]
            if pts:
                x, y = np.array(pts, float).T
                ax.plot(x, y, "o-", color=colour, label=f"{plant_title(plant)}: points")
            mesh = next((get(r) for r in mine if r["size_m"] is None), None)
            if mesh is not None:
                ax.axhline(mesh, color=colour, ls="--", lw=1, label=f"{plant_title(plant)}: mesh")
        ax.set_xscale("log")
        ax.set_xlabel("point size (diameter, mm)")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        if title.startswith(("Precision", "Recall")):
            ax.set_ylim(0, 1.05)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper right", ncols=min(len(labels), 4), fontsize=8)
    fig.suptitle("Plants as points of growing size (the paper's Table 3)", fontsize=11)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()
