"""The ``pybullet`` physics backend: the cell simulated with dynamics in DIRECT mode.

Arms are driven by pybullet's joint position motors (gains and force limits configurable: the
paper's "arm dynamics options") stepping at ``rate`` Hz; what the arms actually did is reported
back. Collision queries for planners run in a second, kinematic-only pybullet world so that
probing configurations never disturbs the simulated state.
"""

from __future__ import annotations

from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import PhysicsCapabilities
from agrisim.kinds import lazy


class BulletOptions(Options):
    """Options of the pybullet physics backend."""

    rate: float = Field(240.0, ge=240.0, le=10000.0)
    """Simulation steps per second (at least 240 Hz)."""
    position_gain: float = Field(0.3, gt=0.0, le=1.0)
    """Position gain of the joint motors (pybullet's ``positionGain``)."""
    velocity_gain: float = Field(1.0, ge=0.0, le=10.0)
    """Velocity gain of the joint motors (pybullet's ``velocityGain``)."""
    force_scale: float = Field(1.0, gt=0.0, le=10.0)
    """Scale on the URDF's joint effort limits used as motor force limits."""
    gravity: float = Field(9.81, ge=0.0, le=100.0)
    """Gravity, m/s^2 (pointing down)."""
    clearance: float = Field(0.005, ge=0.0, le=0.2)
    """Distance below which planning queries count as a collision, m: room for the arm's
    tracking error, so executed motions stay collision-free."""


@hookimpl
def agrisim_physics() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="pybullet",
            factory=lazy("agrisim.plugins.physics.pybullet_physics.backend:BulletPhysics"),
            description="pybullet dynamics (DIRECT), joint position motors with configurable gains and force limits",
            options_model=BulletOptions,
            limits="rigid bodies only; contacts are detected and reported, not resolved into the plan",
            capabilities=PhysicsCapabilities(dynamics=True),
        )
    ]
