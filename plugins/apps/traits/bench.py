"""``agrisim traits RUN`` of a run on a bench: each plant's traits, exact from its model grown
alone (its species or file, its seed), in its own frame (z up from its soil, its stem at
x = y = 0), one row a plant, and ``traits.json``'s ``plants`` (each plant's document as one
plant's traits.json has it, with where its pot stands)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from agrisim.config import RunConfig
from agrisim.plant_choice import bench_configs, resolve_plant
from agrisim.plugins.apps.traits.document import traits_document
from agrisim.plugins.apps.traits.truth import PlantTraits, plant_traits
from agrisim.registry import Registry
from agrisim.scene.model import BenchPlant


@dataclass
class BenchRow:
    """One plant of a bench: where it stands, the name it grew under, its traits and its
    traits.json document (:func:`traits_document`'s)."""

    slot: BenchPlant
    name: str
    traits: PlantTraits
    document: dict[str, Any]


def bench_traits(
    registry: Registry, config: RunConfig, progress: Callable[[str, int, int], None] | None = None
) -> list[BenchRow]:
    """Each plant of ``config``'s bench grown alone and its traits; ``progress(plant, done,
    total)`` hears of each plant's triangles cut."""
    out = []
    for slot, alone in bench_configs(registry, config):
        plant = resolve_plant(registry, alone)

        def tell(done: int, total: int, name: str = slot.name) -> None:
            if progress is not None:
                progress(name, done, total)

        truth = plant_traits(plant, tell)
        out.append(BenchRow(slot, plant.name, truth, traits_document(plant, slot.seed, truth)))
    return out


def bench_document(rows: list[BenchRow]) -> dict[str, Any]:
    """traits.json of a bench: each plant's document (:func:`traits_document`'s ``plant`` and
    ``leaves``, with ``xy``: its pot from the bench's centre, m) by plant name, and what one
    plant's document says of units and definitions."""
    plants = {
        r.slot.name: {"plant": r.document["plant"], "xy": list(r.slot.xy), "leaves": r.document["leaves"]} for r in rows
    }
    common = {k: v for k, v in rows[0].document.items() if k not in ("plant", "leaves", "frame")}
    return {**common, "frame": "each plant's own: z up from its soil, its stem at x = y = 0", "plants": plants}


def print_bench(rows: list[BenchRow]) -> None:
    """The bench's traits, one row a plant."""
    width = max(len("species"), *(len(r.name) for r in rows))
    print(
        f"{'plant':<8}  {'species':<{width}}  {'seed':>4}  {'x m':>6}  {'y m':>6}  {'leaves':>6}  {'leaf cm^2':>9}  "
        f"{'height cm':>9}  {'crown cm':>8}  {'hull L':>6}  {'proj cm^2':>9}  {'incl deg':>8}  de Wit"
    )
    for r in rows:
        slot, name, t = r.slot, r.name, r.traits
        print(
            f"{slot.name:<8}  {name:<{width}}  {slot.seed:>4}  {slot.xy[0]:>6.3f}  {slot.xy[1]:>6.3f}  "
            f"{t.leaf_count:>6}  {t.leaf_area_m2 * 1e4:>9.1f}  {t.height_m * 100:>9.1f}  "
            f"{t.crown_diameter_m * 100:>8.1f}  {t.convex_hull_volume_m3 * 1e3:>6.2f}  "
            f"{t.projected_area_m2 * 1e4:>9.1f}  {t.mean_inclination_deg:>8.1f}  {t.de_wit_class}"
        )
