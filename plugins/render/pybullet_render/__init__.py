"""The ``pybullet`` renderer: TinyRenderer through ``getCameraImage``, the baseline a pybullet
user would reach for.

Its limits are those of TinyRenderer: one directional light, no opacity (cut-out texels are drawn
with the texture's colour and block the view, so its masks are what the paper calls RepOpa), an
object-level segmentation mask (the plant is label 1; no organs), back faces culled (double-sided
cards get reversed copies of their triangles). Depth comes from its z-buffer, converted to metric
planar z with the projection's near and far planes; it is not exact (about 0.5% off on a tilted
floor made of large triangles, see the tests).
"""

from __future__ import annotations

from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import RendererCapabilities
from agrisim.kinds import lazy


class PybulletRenderOptions(Options):
    """Options of the pybullet (TinyRenderer) renderer."""

    near: float = Field(0.02, gt=0.0, le=1.0)
    """Near clipping plane, m."""
    far: float = Field(20.0, gt=1.0, le=1000.0)
    """Far clipping plane, m (nothing beyond it is drawn)."""
    ambient: float = Field(0.45, ge=0.0, le=1.0)
    """Ambient light coefficient."""
    diffuse: float = Field(0.6, ge=0.0, le=1.0)
    """Diffuse light coefficient."""
    shadows: bool = True
    """Shadow-mapped shadows of the first light."""


@hookimpl
def agrisim_renderers() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="pybullet",
            factory=lazy("agrisim.plugins.render.pybullet_render.renderer:PybulletRenderer"),
            description="pybullet TinyRenderer (getCameraImage): the baseline, one directional light",
            options_model=PybulletRenderOptions,
            limits="no opacity cut-outs (masks are RepOpa-like), object-level mask only (label 1 = plant, "
            "no organs), one directional light, hard shadows only, depth ~0.5% off on large tilted triangles",
            capabilities=RendererCapabilities(seg_modes=frozenset({"repopa"})),  # TinyRenderer ignores opacity,
        )
    ]
