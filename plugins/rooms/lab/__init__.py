"""The paper's laboratory around the cell (the ``lab`` room): a tiled room with painted walls,
the table, pot and stands drawn at the cell's sizes, four area lights and the seeded clutter of
the paper's section 3.3 (:mod:`.room`, :mod:`.clutter`, procedural :mod:`.textures`)."""

from __future__ import annotations

from agrisim import BackendSpec, hookimpl
from agrisim.kinds import lazy


@hookimpl
def agrisim_rooms() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="lab",
            factory=lazy("agrisim.plugins.rooms.lab.room:Lab"),
            description="the paper's laboratory: 10 x 8 m, tiled floor, four area lights, cabinets, pallets and "
            "drums placed from pcg_seed",
        )
    ]
