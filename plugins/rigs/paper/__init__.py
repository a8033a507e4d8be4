"""The paper's rig (the ``paper`` rig): two UR10s with a camera on the flange, on stands either
side of the plant table, and the hemisphere routine (:mod:`.cell`)."""

from __future__ import annotations

from agrisim import BackendSpec, hookimpl
from agrisim.kinds import lazy


@hookimpl
def agrisim_rigs() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="paper",
            factory=lazy("agrisim.plugins.rigs.paper.cell:PaperRig"),
            description="the paper's cell: one or two UR10s on stands either side of the plant, cameras on "
            "their flanges; the hemisphere routine",
        )
    ]
