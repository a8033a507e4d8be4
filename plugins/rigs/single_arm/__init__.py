"""The ``single-arm`` rig: one arm from any URDF on a stand beside the plant table, a camera on
its tool link, and the half of the paper's hemisphere that faces it (:mod:`.cell`).

The arm is one of example-robot-data's (``robot``: :data:`.robots.ROBOTS`) or a user's URDF
(``urdf`` with ``camera_link``); :mod:`.urdf_camera` makes its URDF ready, :mod:`.layout`
sizes the cell by what it reaches.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field, field_validator, model_validator

from agrisim import BackendSpec, Options, hookimpl
from agrisim.kinds import lazy
from agrisim.plugins.rigs.single_arm.robots import ROBOTS


class SingleArmOptions(Options):
    """Options of the ``single-arm`` rig (``[rig.single-arm]``)."""

    robot: str = "ur10"
    """The arm, one of example-robot-data's: ur3, ur5, ur10, panda, xarm7, kinova, z1 (so101
    is refused: its 5 joints cannot set a camera pose). Ignored when ``urdf`` is given."""
    urdf: Path | None = None
    """A URDF file of your own arm instead (``--robot-urdf``); its relative and ``package://``
    mesh names are resolved against its folder."""
    camera_link: str | None = None
    """The link of ``urdf`` the camera mounts on (``--camera-link``); required with ``urdf``."""
    camera_xyz: tuple[float, float, float] | None = None
    """The camera body's centre in the mount link, m (default: the robot's own, beyond its tool;
    ``0 0 0.025`` for a user's URDF)."""
    camera_rpy: tuple[float, float, float] | None = None
    """Roll, pitch, yaw of the camera body in the mount link, rad; the body's +x is the optical
    axis (default: pointing out of the tool; a user's URDF: along the link's +z, ``0 -pi/2 0``)."""
    distance: float | None = Field(default=None, gt=0.1, le=3.0)
    """Horizontal distance from the plant centre to the arm's base, m (default: from its reach)."""
    radius: float | None = Field(default=None, gt=0.05, le=1.5)
    """Radius of the hemisphere of viewpoints, m (default: from its reach; replaces
    ``[routine] radius``)."""
    stand_height: float | None = Field(default=None, ge=0.0, le=3.0)
    """Height of the arm's stand, m (default: the shoulder level with the point cameras aim at)."""
    home: list[float] | None = None
    """The arm's starting joints, rad (default: a collision-free configuration looking at the plant)."""

    @field_validator("robot")
    @classmethod
    def _known(cls, name: str) -> str:
        if name not in ROBOTS:
            raise ValueError(f"unknown robot {name!r}; robots: {', '.join(ROBOTS)}")
        return name

    @model_validator(mode="after")
    def _link_with_urdf(self) -> SingleArmOptions:
        if self.urdf is not None and not self.camera_link:
            raise ValueError("urdf needs camera_link, the link its camera mounts on")
        if self.camera_link is not None and self.urdf is None:
            raise ValueError("camera_link goes with urdf (a URDF of your own)")
        return self


@hookimpl
def agrisim_rigs() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="single-arm",
            factory=lazy("agrisim.plugins.rigs.single_arm.cell:SingleArmRig"),
            description="one arm from example-robot-data or your URDF on a stand beside the plant, a camera on "
            "its tool; the half hemisphere facing it",
            options_model=SingleArmOptions,
        )
    ]
