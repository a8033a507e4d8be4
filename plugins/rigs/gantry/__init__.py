"""The ``gantry`` rig: a Cartesian XYZ stage over the plant, its vertical ram carrying a pan-tilt
camera, in a portal frame (four posts and two rails) around the plant table, as in greenhouse
and field phenotyping gantries. Its routine is the whole hemisphere around the plant for one
camera, each viewpoint's joints solved in closed form (:mod:`.cell`).

The optical centre lies on both the pan and the tilt axis (:mod:`.urdf`), so the camera's
position is the stage's (x, y, z) and its orientation the head's pan then tilt: every viewpoint
that looks at the plant without rolling the image is reached by exactly one set of joints.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from agrisim import BackendSpec, Options, hookimpl
from agrisim.kinds import lazy


class GantryOptions(Options):
    """Options of the ``gantry`` rig (``[rig.gantry]``)."""

    travel_x: float | None = Field(default=None, gt=0.1, le=8.0)
    """The stage's travel along x, m, centred on the plant: the camera reaches x within
    plus or minus half of it. The portal's posts stand outside it. None: 1.2 m, plus twice the
    farthest plant's x on a bench."""
    travel_y: float | None = Field(default=None, gt=0.1, le=8.0)
    """The stage's travel along y, m, centred on the plant; None: 1.2 m, plus twice the
    farthest plant's y on a bench."""
    beam_height: float = Field(default=1.8, gt=0.5, le=2.8)
    """Height of the portal's rails (the top of the frame the bridge rides on) above the floor, m.
    The camera reaches up to a head's height below it (the head clear of the carriage above)."""
    z_min: float = Field(default=0.85, gt=0.0, le=2.5)
    """The lowest the camera's optical centre may go (the ram's lower limit), m above the floor."""
    speed_x: float = Field(default=0.3, gt=0.0, le=5.0)
    """The x axis's speed limit, m/s (its joint's velocity limit: Ruckig times every move by the
    limits, the accelerations below and ``[motion]``'s jerk)."""
    speed_y: float = Field(default=0.3, gt=0.0, le=5.0)
    """The y axis's speed limit, m/s."""
    speed_z: float = Field(default=0.2, gt=0.0, le=5.0)
    """The vertical ram's speed limit, m/s."""
    pan_tilt_speed_deg_s: float = Field(default=90.0, gt=0.0, le=720.0)
    """The pan-tilt head's speed limit, degrees a second (both axes)."""
    acceleration: float = Field(default=0.5, gt=0.0, le=20.0)
    """The x, y and z axes' acceleration limit, m/s^2 (a belt-driven gantry's; within ``[motion]
    max_acceleration`` too)."""
    pan_tilt_acceleration_deg_s2: float = Field(default=180.0, gt=0.0, le=3600.0)
    """The pan-tilt head's acceleration limit, degrees a second squared."""

    @model_validator(mode="after")
    def _fits(self) -> GantryOptions:
        # here rather than at the top: listing the rigs should not load the URDF builder
        from agrisim.plugins.rigs.gantry.urdf import HEAD_TOP

        top = self.beam_height - HEAD_TOP
        if self.z_min >= top:
            raise ValueError(
                f"z_min {self.z_min} m leaves the ram no stroke: the camera goes up to {top:.2f} m "
                f"under rails at beam_height {self.beam_height} m"
            )
        return self


@hookimpl
def agrisim_rigs() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="gantry",
            factory=lazy("agrisim.plugins.rigs.gantry.cell:GantryRig"),
            description="a Cartesian XYZ gantry over the plant with a pan-tilt camera on its ram; the whole "
            "hemisphere for one camera",
            options_model=GantryOptions,
        )
    ]
