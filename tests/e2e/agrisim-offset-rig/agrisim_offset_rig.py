"""The ``offset`` rig: the paper's cell (agrisim's ``paper`` rig, sized by ``[cell]``) with every
arm and its stand moved ``shift`` metres along +y, the table and pot left where they are; the
paper's hemisphere, which turns each arm's half to face its base, as the default viewpoints."""

from __future__ import annotations

import dataclasses

from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.config import RoutineConfig
from agrisim.interfaces import Rig
from agrisim.plugins.rigs.paper.cell import build_cell, hemisphere
from agrisim.robot.cell import Cell
from agrisim.robot.setpoints import Setpoint
from agrisim.scene.transforms import translation


class OffsetOptions(Options):
    shift: float = Field(default=0.3, ge=-1.0, le=1.0)
    """How far the arms and their stands move along +y, m."""
    arms: int = Field(default=2, ge=0, le=2)
    """How many of the paper's arms the cell keeps (0: a rig with no camera, which a run refuses)."""


class OffsetRig(Rig):
    def cell(self) -> Cell:
        paper = build_cell(self.settings)
        move = translation(0.0, self.options.shift, 0.0)
        stands = {arm.stand for arm in paper.arms}
        return dataclasses.replace(
            paper,
            arms=tuple(dataclasses.replace(a, world_T_base=move @ a.world_T_base) for a in paper.arms)[
                : self.options.arms
            ],
            obstacles=tuple(
                dataclasses.replace(ob, world_T=move @ ob.world_T) if ob.name in stands else ob
                for ob in paper.obstacles
            ),
        )

    def setpoints(self, cell: Cell, routine: RoutineConfig) -> dict[str, list[Setpoint]]:
        return hemisphere(cell, routine)


@hookimpl
def agrisim_rigs() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="offset",
            factory=OffsetRig,
            description="the paper's cell with its arms and stands moved sideways",
            options_model=OffsetOptions,
        )
    ]
