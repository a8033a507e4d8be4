"""The ``cabinet`` room: a turntable phenotyping station's imaging cabinet (LemnaTec Scanalyzer 3D
style) around the cell, every surface and light symmetric about the stage axis, the vertical line
through the cell's ``plant_center`` (:mod:`.room`).

A turntable rig simulates its views in the stage's frame: the plant stands still and the cameras
orbit it by minus the stage's angle. That gives exactly the turntable's images only where all that
does not turn with the stage looks the same from every angle about the axis, which is what this
room is built to be.
"""

from __future__ import annotations

from pydantic import Field, field_validator

from agrisim import BackendSpec, Options, hookimpl
from agrisim.kinds import lazy

Colour = tuple[float, float, float]


class CabinetOptions(Options):
    """Options of the ``cabinet`` room (``[room.cabinet]``)."""

    radius: float = Field(default=1.5, gt=0.2, le=10.0)
    """Radius of the cylindrical backdrop (and of the floor and ceiling discs) about the stage
    axis, m. It must clear every obstacle and arm base of the rig (the paper's stands reach
    1.22 m); the cameras should stay inside it too."""
    height: float = Field(default=2.4, gt=0.5, le=10.0)
    """Height of the ceiling above the floor, m; the lamp hangs just below it."""
    backdrop_color: Colour = (0.56, 0.65, 0.72)
    """Linear RGB of the backdrop: matte, a light blue-grey like LemnaTec's (sRGB about
    0.78, 0.83, 0.87); ``1 1 1`` for white."""
    floor_color: Colour = (0.30, 0.30, 0.31)
    """Linear RGB of the floor disc."""
    ceiling_color: Colour = (0.80, 0.80, 0.80)
    """Linear RGB of the ceiling disc."""
    obstacle_color: Colour = (0.62, 0.63, 0.65)
    """Linear RGB of the table, stands and other obstacles (the pot is the lab's terracotta)."""
    stage_radius: float = Field(default=0.15, gt=0.0, le=2.0)
    """Radius of the turntable's plate under the pot, m (at least the pot's radius plus 1 cm)."""
    stage_height: float = Field(default=0.02, ge=0.0, le=0.5)
    """Thickness of the plate, m: it stands on whatever the pot stands on, the pot's lowest
    ``stage_height`` inside it; 0: no plate."""
    stage_color: Colour = (0.05, 0.05, 0.055)
    """Linear RGB of the plate."""
    lamp_radius: float = Field(default=0.4, ge=0.0, le=5.0)
    """Radius of the ceiling lamp, an area light (a disc) on the axis facing down, m; 0: a spot
    light there instead, a point lighting the lower hemisphere (hard shadows, exactly symmetric
    in the raycast renderer, whose shadow rays aim at points of a disc that are not)."""
    irradiance: float = Field(default=0.7, gt=0.0, le=100.0)
    """Irradiance the lamp gives a surface facing it at the plant's middle height on the axis
    (1: white on white): the lab's two ceiling lights give 0.35 each."""

    @field_validator("backdrop_color", "floor_color", "ceiling_color", "obstacle_color", "stage_color")
    @classmethod
    def _in_unit_range(cls, rgb: Colour) -> Colour:
        if not all(0.0 <= c <= 1.0 for c in rgb):
            raise ValueError(f"each of R, G, B must be in 0..1, got {rgb}")
        return rgb


@hookimpl
def agrisim_rooms() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="cabinet",
            factory=lazy("agrisim.plugins.rooms.cabinet.room:Cabinet"),
            description="a turntable phenotyping cabinet: round backdrop, floor and ceiling about the stage axis, "
            "a turntable plate, one lamp on the axis (symmetric, for a rig that turns the plant)",
            options_model=CabinetOptions,
        )
    ]
