"""The architecture page's picture of the layers (``docs/layers.png``): the core's layers from the
base up, as ``docs/concepts/architecture.md`` lists them (the list the architecture test reads),
each with its modules and its lines of Python, and the plugins above them. Asserts nothing.

    python bench/figure_layers.py [--out docs/layers.png]
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def layers() -> list[tuple[str, list[str]]]:
    """(name, modules) of each layer on the architecture page, from the bottom up."""
    page = (REPO / "docs" / "concepts" / "architecture.md").read_text()
    section = page[page.index("## Layers") : page.index("## The tree")]
    found = [re.match(r"\d+\. \*\*(.+?)\*\*: (.+)$", line) for line in section.splitlines()]
    return [(m.group(1), re.findall(r"`([^`]+)`", m.group(2))) for m in found if m]


def lines_of(name: str) -> int:
    """Lines of Python in a core module or folder (``testing/`` stands beside ``core/``)."""
    root = REPO / ("testing" if name == "testing/" else "core")
    path = root if name == "testing/" else root / name.rstrip("/")
    files = sorted(path.rglob("*.py")) if path.is_dir() else [path.with_suffix(".py")]
    return sum(len(f.read_text().splitlines()) for f in files if f.is_file())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/layers.png"))
    args = parser.parse_args()
    stack = layers()
    plugin_kinds = sorted(p.name for p in (REPO / "plugins").iterdir() if (p / "__init__.py").exists())
    height, gap = 0.62, 0.12
    fig, ax = plt.subplots(figsize=(12, 0.62 * (len(stack) + 2)))
    rows = [(name, mods, "#dbe8f5") for name, mods in stack]
    kinds = [f"{k}/" for k in plugin_kinds]
    half = (len(kinds) + 1) // 2
    rows.append(("plugins", [", ".join(kinds[:half]) + ",\n" + ", ".join(kinds[half:])], "#f3e3c8"))
    for i, (name, mods, colour) in enumerate(rows):
        y = i * (height + gap)
        ax.add_patch(
            FancyBboxPatch((0, y), 8.6, height, boxstyle="round,pad=0.02,rounding_size=0.08", fc=colour, ec="#4a5a6a")
        )
        size = "" if name == "plugins" else f"  ({sum(lines_of(m) for m in mods):,} lines)"
        ax.text(0.15, y + height / 2, name, va="center", ha="left", fontsize=10.5, weight="bold")
        ax.text(1.9, y + height / 2, ", ".join(mods) + size, va="center", ha="left", fontsize=9, family="monospace")
    top = len(rows) * (height + gap)
    ax.add_patch(FancyArrowPatch((10.7, top - 0.2), (10.7, 0.2), arrowstyle="-|>", mutation_scale=18, color="#4a5a6a"))
    ax.text(10.95, top / 2, "imports point down", rotation=90, va="center", ha="center", fontsize=9.5)
    core = sum(lines_of(m) for _, mods in stack for m in mods if m != "testing/")
    ax.set_title(f"agrisim's core ({core:,} lines of Python in core/) and the plugins above it", fontsize=11)
    ax.set_xlim(-0.1, 11.2)
    ax.set_ylim(-0.1, top)
    ax.axis("off")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}: {len(stack)} layers, core {core:,} lines")


if __name__ == "__main__":
    main()
