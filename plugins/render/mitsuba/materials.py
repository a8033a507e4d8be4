"""agrisim materials as Mitsuba BSDFs (plain dicts for ``mitsuba.load_dict``).

* Colour: the albedo texture (sRGB, 8 bits) in linear light times the material's colour factor,
  the same numbers the raycast renderer shades with, given to Mitsuba as raw float data
  (bilinear, repeating); an untextured material is its colour.
* Surfaces: ``principled`` with the material's roughness and metallic (specular 0.5, i.e. a
  dielectric's 4% at normal incidence), wrapped in ``twosided`` when the material is
  double-sided.
* Translucent cards (``Material.transmittance``, leaves): an even ``blendbsdf`` of that reflector
  with twice the albedo and a ``principledthin`` with ``diff_trans = 2`` (a pure diffuse
  transmitter) with twice the transmitted colour. Each half then gives back what it was given:
  reflectance = albedo, transmittance = albedo x transmittance, capped texel by texel so that the
  two never sum past 1 (Mitsuba's ``principledthin`` alone splits one colour between the two
  sides; a leaf transmits a greener light than it reflects).
* Cut-outs (MASK/BLEND): a ``mask`` whose opacity is 1 where the label pass keeps the texel and
  0 where it cuts it (8-bit alpha against :func:`agrisim.scene.texturing.alpha_threshold`, the
  nearest texel), so the RGB has the same holes as the labels.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from agrisim.scene.colour import srgb_to_linear
from agrisim.scene.model import Material
from agrisim.scene.texturing import alpha_threshold

F32 = np.float32
SRGB_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0).astype(F32)


def linear_albedo(material: Material) -> np.ndarray | None:
    """H x W x 3 float32 linear albedo (texture x colour factor), or None when untextured."""
    if material.albedo is None:
        return None
    return SRGB_TO_LINEAR[material.albedo[..., :3]] * np.asarray(material.color[:3], F32)


def opacity(material: Material) -> np.ndarray | float | None:
    """The cut-out mask: H x W x 1 float32 of 0/1, a constant for untextured materials, or None
    when opacity cuts nothing."""
    threshold = alpha_threshold(material)
    if threshold == 0:
        return None
    if material.albedo is None:
        return 1.0 if threshold <= 255 else 0.0
    return (material.albedo[..., 3:4] >= threshold).astype(F32)


class BsdfFactory:
    """Builds the BSDF dict of each material; textures shared by several materials are turned
    into Mitsuba bitmaps once (``texture`` wraps an H x W x C float32 array as one)."""

    def __init__(self, texture: Callable[[np.ndarray, str], Any]) -> None:
        self._texture = texture
        self._made: dict[tuple, Any] = {}

    def _bitmap(self, key: tuple, make: Callable[[], np.ndarray], filter_type: str) -> Any:
        if key not in self._made:
            self._made[key] = self._texture(np.ascontiguousarray(make(), F32), filter_type)
        return self._made[key]

    def _colour(self, material: Material, scale: float = 1.0, tint: np.ndarray | None = None) -> Any:
        """The material's linear colour (times ``scale``, times ``tint``, capped to 1 - albedo
        when tinted), as a texture or an ``rgb`` constant."""
        key = ("colour", id(material.albedo), tuple(material.color[:3]), scale, None if tint is None else tuple(tint))

        def make() -> np.ndarray:
            albedo = linear_albedo(material)
            base = np.asarray(material.color[:3], F32) if albedo is None else albedo
            out = base if tint is None else np.minimum(base * tint, 1.0 - base)
            return out * F32(scale)

        if material.albedo is not None:
            return self._bitmap(key, make, "bilinear")
        return {"type": "rgb", "value": [float(c) for c in make()]}

    def _reflector(self, material: Material, scale: float = 1.0) -> dict:
        return {
            "type": "principled",
            "base_color": self._colour(material, scale),
            "roughness": float(material.roughness),
            "metallic": float(material.metallic),
            "specular": 0.5,
        }

    def bsdf(self, material: Material) -> dict:
        """The BSDF dict of ``material``."""
        if material.transmittance is not None:
            tint = np.asarray(material.transmittance, F32)
            surface: dict = {
                "type": "blendbsdf",
                "weight": 0.5,
                "reflect": {"type": "twosided", "bsdf": self._reflector(material, 2.0)},
                "transmit": {
                    "type": "principledthin",
                    "base_color": self._colour(material, 2.0, tint),
                    "diff_trans": 2.0,
                    "spec_trans": 0.0,
                    "roughness": float(material.roughness),
                },
            }
        elif material.double_sided:
            surface = {"type": "twosided", "bsdf": self._reflector(material)}
        else:
            surface = self._reflector(material)
        cut = opacity(material)
        if cut is None:
            return surface
        if isinstance(cut, float):
            mask: Any = {"type": "uniform", "value": cut}
        else:
            mask = self._bitmap(("opacity", id(material.albedo), alpha_threshold(material)), lambda: cut, "nearest")
        return {"type": "mask", "opacity": mask, "bsdf": surface}
