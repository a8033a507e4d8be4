"""Vertex colours in Mitsuba: a texture that multiplies another by the mesh's ``vertex_color``
attribute (glTF's ``COLOR_0``, :attr:`agrisim.scene.model.Mesh.colors`), interpolated over the
triangle as UVs are. Mitsuba's ``mesh_attribute`` texture reads the attribute, but none of its
textures multiplies two, so this one is written in Python (Dr.Jit traces it into the kernel like
any other texture, on the CPU and the GPU).

:func:`tinted` wraps a colour (a texture object or an ``rgb`` dict) for a mesh that has the
attribute; :func:`register` makes the plugin known to the current variant once.
"""

from __future__ import annotations

from typing import Any

import drjit as dr

PLUGIN = "agrisim_vertex_tint"
ATTRIBUTE = "vertex_color"

_registered: set[str] = set()


def register(mi: Any) -> None:
    """Register the texture with Mitsuba's current variant (again for each variant used)."""
    if mi.variant() in _registered:
        return

    class VertexTint(mi.Texture):  # type: ignore[misc, name-defined]
        """``texture`` times the shape's vertex colour."""

        def __init__(self, props: Any) -> None:
            mi.Texture.__init__(self, props)
            self.nested = props.get_texture("texture")

        def eval(self, si: Any, active: Any = True) -> Any:
            tint = si.shape.eval_attribute_3(ATTRIBUTE, si, active)
            return self.nested.eval(si, active) * mi.Color3f(tint)

        def eval_1(self, si: Any, active: Any = True) -> Any:
            return dr.mean(self.eval(si, active))

        def mean(self) -> Any:
            return self.nested.mean()

        def is_spatially_varying(self) -> bool:
            return True

        def traverse(self, callback: Any) -> None:
            callback.put("texture", self.nested, mi.ParamFlags.NonDifferentiable)

    mi.register_texture(PLUGIN, lambda props: VertexTint(props))
    _registered.add(mi.variant())


def tinted(colour: Any) -> dict:
    """``colour`` (a Mitsuba texture or a texture dict) times the vertex colour."""
    return {"type": PLUGIN, "texture": colour}
