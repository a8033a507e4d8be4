"""The paper's Table 2 from ``metrics.json`` documents: rows, markdown, CSV and a chart.

Pure functions of metrics dictionaries (one per plant and segmentation mode), so a table can be
rebuilt from run directories on disk at any time. Each row carries, per mode, labelled pixels,
points, precision/recall/F-score per threshold and the Chamfer distance, and the paper's
percentage ``100 (RepOpa / Ours - 1)`` for pixels and points. matplotlib is imported only by
:func:`chart_png`.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from agrisim.capabilities import SEG_MODES
from agrisim.files import layout

#: how the table names the modes (the paper's column heads)
MODE_TITLES: dict[str, str] = {"texture": "Ours", "repopa": "RepOpa"}
#: the accuracy measures of ``metrics.json`` that carry one value per threshold
THRESHOLD_METRICS: tuple[str, ...] = ("precision", "recall", "recall_visible", "fscore")
#: the label whose figures make the table's rows: every labelled pixel, the merged cloud
TABLE_LABEL = "all"


def read_metrics(run_dir: Path) -> dict[str, Any] | None:
    """A run directory's ``metrics.json``, or None when it is missing or unreadable."""
    try:
        doc = json.loads((Path(run_dir) / layout.METRICS_JSON).read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def percent_increase(ours: float | None, repopa: float | None) -> float | None:
    """The paper's ``100 (RepOpa / Ours - 1)``; None when either is missing or Ours is 0."""
    if ours is None or repopa is None or ours == 0:
        return None
    return 100.0 * (repopa / ours - 1.0)


def _thr_key(t: float | str) -> str:
    return t if isinstance(t, str) else f"{t:g}"


def table_rows(
    metrics: Mapping[tuple[str, str], Mapping[str, Any] | None],
    plants: Sequence[str],
    seg_modes: Sequence[str] = SEG_MODES,
    *,
    per_label: bool = False,
) -> list[dict[str, Any]]:
    """Rows of the table from ``metrics[(plant, seg_mode)]`` (a ``metrics.json`` or None).

    One row per plant from the label ``all`` (every labelled pixel, the merged cloud); with
    ``per_label`` also one per label the runs name besides it. A row holds, per measure, a
    value per mode (None where a run is missing) and the percentages ``pixels_pct`` and
    ``points_pct`` = ``100 (repopa / texture - 1)``.
    """
    rows = []
    for plant in plants:
        docs = {m: metrics.get((plant, m)) for m in seg_modes}
        labels = [TABLE_LABEL]
        if per_label:
            names = []
            for doc in docs.values():
                for name in (doc or {}).get("labels", {}):
                    if name != TABLE_LABEL and name not in names:
                        names.append(name)
            if len(names) > 1:  # one label "plant" would only repeat "all"
                labels += names
        for label in labels:
            row: dict[str, Any] = {"plant": plant, "label": label}
            entries = {m: ((d or {}).get("labels") or {}).get(label) for m, d in docs.items()}
            for measure in ("pixels", "points", "chamfer_mm"):
                row[measure] = {m: (e or {}).get(measure) for m, e in entries.items()}
            for measure in THRESHOLD_METRICS:
                row[measure] = {m: dict((e or {}).get(measure) or {}) for m, e in entries.items()}
            for measure in ("pixels", "points"):
                row[f"{measure}_pct"] = percent_increase(row[measure].get("texture"), row[measure].get("repopa"))
            row["frames"] = {m: (d or {}).get("frames") for m, d in docs.items()}
            rows.append(row)
    return rows


def thresholds_of(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The thresholds (mm, as ``%g`` strings) the rows carry, in increasing order."""
    keys = {k for r in rows for m in THRESHOLD_METRICS for per_mode in r[m].values() for k in per_mode}
    return sorted(keys, key=float)


def table_threshold(thresholds: Sequence[str]) -> str | None:
    """The one threshold the markdown table shows: 2 mm when measured, else the middle one."""
    if not thresholds:
        return None
    return "2" if "2" in thresholds else thresholds[len(thresholds) // 2]


def plant_key(plant: str) -> str:
    """The run-directory name of a plant: the species name, or a file's stem."""
    return Path(plant).stem if is_file_plant(plant) else plant


def is_file_plant(plant: str) -> bool:
    """Does ``plant`` name an asset file (by its extension) rather than a species?"""
    from agrisim.plugins.formats.plant_asset import FORMATS

    return Path(plant).suffix.lower() in FORMATS


def plant_title(plant: str) -> str:
    """``indian_cress`` -> ``Indian Cress`` (the paper's row names)."""
    return plant_key(plant).replace("_", " ").title()


def _fmt(value: Any, spec: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return format(value, spec)


def markdown_table(rows: Sequence[Mapping[str, Any]], seg_modes: Sequence[str] = SEG_MODES) -> str:
    """The paper's Table 2 in markdown, with precision, recall, F-score (at one threshold) and
    Chamfer distance added. Pixels in 10^6 as in the paper; % is ``100 (RepOpa / Ours - 1)``."""
    rows = [r for r in rows if r["label"] == TABLE_LABEL]
    thr = table_threshold(thresholds_of(rows))
    both = all(m in seg_modes for m in SEG_MODES)
    heads = ["Plant"]
    for title in ("Pixels (10^6)", "Points"):
        heads += [f"{title} {MODE_TITLES[m]}" for m in seg_modes] + (["%"] if both else [])
    extra = [("precision", "Precision"), ("recall", "Recall"), ("fscore", "F-score")] if thr else []
    for _, title in extra:
        heads += [f"{title}@{thr}mm {MODE_TITLES[m]}" for m in seg_modes]
    heads += [f"Chamfer (mm) {MODE_TITLES[m]}" for m in seg_modes]
    lines = ["| " + " | ".join(heads) + " |", "|" + "|".join(["---"] + ["---:"] * (len(heads) - 1)) + "|"]
    for r in rows:
        cells = [plant_title(r["plant"])]
        px = r["pixels"]
        cells += [_fmt(None if px[m] is None else px[m] / 1e6, ".3f") for m in seg_modes]
        cells += [_fmt(r["pixels_pct"], ".2f")] if both else []
        cells += [_fmt(r["points"][m], "d") for m in seg_modes]
        cells += [_fmt(r["points_pct"], ".2f")] if both else []
        for measure, _ in extra:
            cells += [_fmt(r[measure][m].get(thr), ".3f") for m in seg_modes]
        cells += [_fmt(r["chamfer_mm"][m], ".2f") for m in seg_modes]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def csv_table(rows: Sequence[Mapping[str, Any]], seg_modes: Sequence[str] = SEG_MODES) -> str:
    """The table as CSV: one row per plant and label, raw counts, every threshold; columns
    ``pixels_texture, pixels_repopa, pixels_pct, ..., precision_2mm_texture, ...``. Missing
    values are empty cells."""
    thresholds = thresholds_of(rows)
    cols = ["plant", "label"]
    for measure in ("pixels", "points"):
        cols += [f"{measure}_{m}" for m in seg_modes] + [f"{measure}_pct"]
    for measure in THRESHOLD_METRICS:
        cols += [f"{measure}_{t}mm_{m}" for t in thresholds for m in seg_modes]
    cols += [f"chamfer_mm_{m}" for m in seg_modes] + [f"frames_{m}" for m in seg_modes]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(cols)
    for r in rows:
        values: list[Any] = [r["plant"], r["label"]]
        for measure in ("pixels", "points"):
            values += [r[measure][m] for m in seg_modes] + [r[f"{measure}_pct"]]
        for measure in THRESHOLD_METRICS:
            values += [r[measure][m].get(t) for t in thresholds for m in seg_modes]
        values += [r["chamfer_mm"][m] for m in seg_modes] + [r["frames"][m] for m in seg_modes]
        # repr-exact floats: the CSV is for further computation, not for reading
        writer.writerow(["" if v is None else repr(v) if isinstance(v, float) else v for v in values])
    return buf.getvalue()


def chart_png(rows: Sequence[Mapping[str, Any]], seg_modes: Sequence[str] = SEG_MODES, title: str = "") -> bytes:
    """Grouped bar charts, Ours against RepOpa per plant: labelled pixels and points (each pair
    annotated with the paper's %), precision and F-score at the table's threshold."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = [r for r in rows if r["label"] == TABLE_LABEL]
    thr = table_threshold(thresholds_of(rows))
    colours = {"texture": "#3a923a", "repopa": "#d1495b"}
    names = [plant_title(r["plant"]) for r in rows]
    x = np.arange(len(rows))
    width = 0.8 / max(len(seg_modes), 1)
    panels: list[tuple[str, Callable[[Mapping[str, Any], str], Any], str | None]] = [
        ("Labelled pixels (10^6)", lambda r, m: None if r["pixels"][m] is None else r["pixels"][m] / 1e6, "pixels_pct"),
        (
            "Points in the merged cloud (10^3)",
            lambda r, m: None if r["points"][m] is None else r["points"][m] / 1e3,
            "points_pct",
        ),
    ]
    if thr:
        panels += [
            (f"Precision at {thr} mm", lambda r, m: r["precision"][m].get(thr), None),
            (f"F-score at {thr} mm", lambda r, m: r["fscore"][m].get(thr), None),
        ]
    ncols = 2 if len(panels) > 2 else 1
    nrows = math.ceil(len(panels) / ncols)
    fig = Figure(figsize=(ncols * max(6.0, 0.7 * len(rows) + 2.0), 3.4 * nrows + 0.6), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, sharex=True, squeeze=False).ravel()
    for ax in axes[len(panels) :]:
        ax.set_visible(False)
    for ax, (label, get, pct) in zip(axes, panels, strict=False):  # the grid may have an axis spare
        tops = np.zeros(len(rows))
        for k, mode in enumerate(seg_modes):
            values = np.array([np.nan if get(r, mode) is None else float(get(r, mode)) for r in rows])
            ax.bar(
                x + (k - (len(seg_modes) - 1) / 2) * width,
                values,
                width,
                label=MODE_TITLES[mode],
                color=colours.get(mode),
            )
            tops = np.fmax(tops, np.nan_to_num(values))
        if pct and all(m in seg_modes for m in SEG_MODES):
            for xi, r, top in zip(x, rows, tops, strict=True):
                if r[pct] is not None:
                    ax.annotate(
                        f"{r[pct]:+.1f}%",
                        (xi, top),
                        textcoords="offset points",
                        xytext=(0, 2),
                        ha="center",
                        va="bottom",
                        fontsize=8,
                    )
            ax.margins(y=0.15)
        if label.startswith(("Precision", "F-score")):
            ax.set_ylim(0, 1.05)
        ax.set_title(label, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        ax.set_xticks(x, names, rotation=30, ha="right", fontsize=8)
        ax.tick_params(labelbottom=True)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper right", ncols=len(labels), fontsize=9)
    if title:
        fig.suptitle(title, fontsize=11)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()
