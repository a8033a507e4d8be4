"""The ``turntable`` rig: the plant on a rotating stage (a round table) and one to three cameras
fixed on a column beside it, as in 3D phenotyping stations (LemnaTec's Scanalyzer 3D and
university rigs). The routine is the stage's angles times the cameras (:mod:`.cell`).

Simulated in the stage's frame: the column and its cameras orbit the standing plant by minus
the stage's angle (:mod:`.urdf`), which is the turntable's image exactly where the room is
symmetric about the stage's axis (the ``cabinet`` room); in the lab the plant keeps its light
as the cameras go round.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import RigCapabilities
from agrisim.kinds import lazy


class TurntableOptions(Options):
    """Options of the ``turntable`` rig (``[rig.turntable]``)."""

    heights: list[float] = Field(default_factory=lambda: [0.45, 0.25, 0.1], min_length=1, max_length=3)
    """Heights of the cameras above the stage's top, m, one per camera (one to three); the
    routine's levels take them in this order (``--setpoints 1x12``: the first camera alone)."""
    tilts_deg: list[float] | None = None
    """Each camera's downward tilt, degrees (default: aimed at ``[routine] aim_height`` above the
    stage's centre)."""
    distance: float = Field(default=0.5, gt=0.1, le=3.0)
    """Horizontal distance from the stage's axis to the cameras, m."""
    stage_radius: float = Field(default=0.3, gt=0.05, le=1.0)
    """Radius of the stage (the round table the pot stands on), m; within ``distance``."""
    stage_speed_deg_s: float = Field(default=30.0, gt=0.0, le=720.0)
    """The stage's top speed, degrees a second (the stage joint's velocity limit: a move's time
    is Ruckig's, with the acceleration below and ``[motion]``'s jerk)."""
    stage_acceleration_deg_s2: float = Field(default=30.0, gt=0.0, le=3600.0)
    """The stage's acceleration limit, degrees a second squared (a pot's plant must not sway:
    a second to top speed; within ``[motion] max_acceleration`` too)."""

    @model_validator(mode="after")
    def _fits(self) -> TurntableOptions:
        if self.tilts_deg is not None and len(self.tilts_deg) != len(self.heights):
            raise ValueError(f"tilts_deg gives {len(self.tilts_deg)} tilts for {len(self.heights)} cameras")
        if self.tilts_deg is not None and any(not -90.0 < t < 90.0 for t in self.tilts_deg):
            raise ValueError("tilts_deg must lie between -90 and 90 degrees")
        if self.stage_radius + 0.05 > self.distance:
            raise ValueError(f"stage_radius {self.stage_radius} m leaves the cameras at {self.distance} m no room")
        return self


@hookimpl
def agrisim_rigs() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="turntable",
            factory=lazy("agrisim.plugins.rigs.turntable.cell:TurntableRig"),
            description="the plant on a rotating stage, one to three cameras fixed on a column; the stage's "
            "angles times the cameras",
            options_model=TurntableOptions,
            # the cabinet is symmetric about the stage's axis: simulated in the stage's frame, the
            # views are those of the turned plant in front of fixed cameras (the lab would turn)
            capabilities=RigCapabilities(room="cabinet"),
        )
    ]
