"""The ``kinematic`` physics backend: Pinocchio kinematics, coal collisions, perfect tracking.

Every arm follows its plan exactly (no dynamics, no controller lag), so what it reports is
the plan resampled at ``rate``. Collisions are checked, not simulated: all arms and the cell's
obstacles live in one Pinocchio model and one collision ``GeometryModel`` (the URDFs' STL
collision meshes plus coal boxes and cylinders for the cell), so one ``computeCollisions`` call
runs forward kinematics, placement updates and every narrow-phase test in C++.

Which pairs are tested:

* self: two geometries of one arm unless they ride on the same joint (links joined by fixed
  joints, e.g. ``wrist_3_link``/``ee_link``/``camera_link``, are one rigid body) or on joints that
  are parent and child in the kinematic tree;
* cell: each arm geometry against each obstacle, except the arm's base against its own stand;
* arms: each geometry of one arm against each geometry of another.

A query for one arm activates only the pairs that involve it (``arms_in_collision`` only the
arm-against-arm pairs). This module never imports pybullet.
"""

from __future__ import annotations

from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import PhysicsCapabilities
from agrisim.kinds import lazy


class KinematicOptions(Options):
    """Options of the kinematic (perfect-tracking) physics backend."""

    rate: float = Field(240.0, gt=0.0, le=100000.0)
    """Samples per second of executed trajectories, Hz; every sample is collision-checked."""
    margin: float = Field(0.0, ge=0.0, le=0.1)
    """Clearance, m, kept from the cell and the other arms: closer counts as colliding (0 = touching).
    Not applied within one arm, whose links are 2 cm apart at home; above 0.038 an arm's shoulder
    reaches its own stand at home."""
    check_contacts: bool = True
    """Collision-check executed trajectories and report contacts (off: faster, reports none)."""


@hookimpl
def agrisim_physics() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="kinematic",
            factory=lazy("agrisim.plugins.physics.kinematic.backend:KinematicPhysics"),
            description="perfect tracking on Pinocchio kinematics with coal collision checks; no dynamics, no pybullet",
            options_model=KinematicOptions,
            limits="no dynamics: arms follow plans exactly and contacts are reported, never resolved or felt",
            capabilities=PhysicsCapabilities(dynamics=False),
        )
    ]
