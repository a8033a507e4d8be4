"""agrisim materials as Mitsuba BSDFs (plain dicts for ``mitsuba.load_dict``).

* Colour: the albedo texture (sRGB, 8 bits) in linear light times the material's colour factor,
  the same numbers the raycast renderer shades with, given to Mitsuba as raw float data
  (bilinear, repeating); an untextured material is its colour.
* Surfaces: ``principled`` with the material's roughness and metallic (specular 0.5, i.e. a
  dielectric's 4% at normal incidence), times glTF's metallic-roughness texture where there is
  one, wrapped in ``twosided`` when the material is double-sided; a normal map wraps that in
  ``normalmap`` (see :meth:`BsdfFactory._normals` for the tangent frame).
* Translucent cards (``Material.transmittance``, leaves): an even ``blendbsdf`` of that reflector
  with twice the albedo and a ``principledthin`` with ``diff_trans = 2`` (a pure diffuse
  transmitter) with twice the transmitted colour. Each half then gives back what it was given:
  reflectance = albedo, transmittance = albedo x transmittance, capped texel by texel so that the
  two never sum past 1 (Mitsuba's ``principledthin`` alone splits one colour between the two
  sides; a leaf transmits a greener light than it reflects). A transmission texture (glTF's
  diffuse transmission colour, ``Material.transmission``) is the transmitted colour itself.
* Vertex colours (``Mesh.colors``, glTF's ``COLOR_0``): every colour above, of both sides and
  the transmitted one, times the vertex colour (:mod:`.vertex_tint`); the caps hold, since the
  colours are at most 1.
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

from .vertex_tint import VertexColours, tinted

F32 = np.float32
SRGB_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0).astype(F32)


def linear_albedo(material: Material) -> np.ndarray | None:
    """H x W x 3 float32 linear albedo (texture x colour factor), or None when untextured."""
    if material.albedo is None:
        return None
    return SRGB_TO_LINEAR[material.albedo[..., :3]] * np.asarray(material.color[:3], F32)


def mirrored_faces(faces: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """Per face, whether its UVs are mirrored against glTF's usual layout, i.e. whether
    dp/du x dp/dv points along the face's normal (v grows down the image, so an unmirrored
    face has them opposed). Degenerate UVs count as unmirrored."""
    # With p = p0 + [e1 e2] M^-1 (uv - uv0), M = [d1 d2], dp/du x dp/dv = (e1 x e2) / det M:
    # its sign against the face normal e1 x e2 is that of the UV triangle's signed area.
    t = uvs[faces].astype(np.float64)
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    return d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0] > 0.0


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
    into Mitsuba bitmaps once (``texture`` wraps an H x W x C float32 array as one); tinted
    colours read the vertex colours of ``colours``."""

    def __init__(self, texture: Callable[[np.ndarray, str], Any], colours: VertexColours | None = None) -> None:
        self._texture = texture
        self._colours = VertexColours() if colours is None else colours
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
        value = make()
        if value.max() > 1.0:  # (the blend's doubled colours: Mitsuba refuses rgb reflectances above 1)
            return self._bitmap(key, lambda: value.reshape(1, 1, 3), "nearest")
        return {"type": "rgb", "value": [float(c) for c in value]}

    def _channel(self, material: Material, channel: int, factor: float) -> Any:
        """Roughness (channel 1) or metallic (channel 2): the factor, times the texture's
        channel (linear) where the material has one."""
        texture = material.metallic_roughness
        if texture is None:
            return float(factor)
        key = ("mr", id(texture), channel, factor)
        return self._bitmap(key, lambda: texture[..., channel : channel + 1] * F32(factor / 255.0), "bilinear")

    def _transmitted(self, material: Material, tint: bool) -> Any:
        """Twice the transmitted colour (the blend halves it): the transmission texture in
        linear light, or the albedo times the transmittance, capped to 1 - albedo; times the
        vertex colour with ``tint``."""
        if material.transmission is None:
            colour = self._colour(material, 2.0, np.asarray(material.transmittance, F32))
        else:
            texture = material.transmission
            colour = self._bitmap(("transmission", id(texture)), lambda: SRGB_TO_LINEAR[texture] * F32(2.0), "bilinear")
        return tinted(colour, self._colours) if tint else colour

    def _reflector(
        self, material: Material, scale: float = 1.0, colour: Any = None, roughness: Any = None, tint: bool = False
    ) -> dict:
        """The material's reflector; ``colour`` and ``roughness`` in place of its own (a back
        side); its colour times the vertex colour with ``tint``."""
        base = self._colour(material, scale) if colour is None else colour
        return {
            "type": "principled",
            "base_color": tinted(base, self._colours) if tint else base,
            "roughness": self._channel(material, 1, material.roughness) if roughness is None else roughness,
            "metallic": self._channel(material, 2, material.metallic),
            "specular": 0.5,
        }

    def _back_reflector(self, material: Material, scale: float = 1.0, tint: bool = False) -> dict:
        """The back side's reflector (``Material.back_color``, ``back_roughness``): the front's
        colour times the back's factors, capped so that with what the surface transmits it
        never passes 1."""
        factor = np.asarray(material.back_color if material.back_color is not None else (1.0, 1.0, 1.0), F32)
        translucent = material.transmittance is not None and material.transmission is None
        through = np.asarray(material.transmittance, F32) if translucent else None
        key = (
            "back",
            id(material.albedo),
            tuple(material.color[:3]),
            tuple(factor),
            scale,
            None if through is None else tuple(through),
        )

        def make() -> np.ndarray:
            albedo = linear_albedo(material)
            base = np.asarray(material.color[:3], F32) if albedo is None else albedo
            passed = np.zeros_like(base) if through is None else np.minimum(base * through, 1.0 - base)
            return np.minimum(base * factor, 1.0 - passed) * F32(scale)

        if material.albedo is not None:
            colour = self._bitmap(key, make, "bilinear")
        else:  # (one texel: Mitsuba refuses rgb reflectances above 1, which the blend's doubling makes)
            colour = self._bitmap(key, lambda: make().reshape(1, 1, 3), "nearest")
        rough = material.back_roughness
        return self._reflector(material, colour=colour, roughness=None if rough is None else float(rough), tint=tint)

    def _sides(self, material: Material, scale: float = 1.0, tint: bool = False) -> dict:
        """Both sides of a double-sided surface: alike, or the back as the material says."""
        front = self._reflector(material, scale, tint=tint)
        if material.back_color is None and material.back_roughness is None:
            return {"type": "twosided", "bsdf": front}
        # (twosided takes its nested BSDFs in order: the front, then the back)
        return {"type": "twosided", "front": front, "back": self._back_reflector(material, scale, tint)}

    def _normals(self, material: Material, mirrored: bool) -> Any:
        """The normal map as Mitsuba reads it: unit vectors encoded as (n + 1) / 2, glTF's
        scale applied, and the bitangent turned to Mitsuba's frame.

        Mitsuba's shading frame has s along dp/du and t = n x s: on a face whose UVs are laid
        out as glTF's usually are (v growing down the image, so dp/du x dp/dv points against
        the normal) t is the image's up, glTF's +y; on a mirrored face it is down, so those
        faces get the map with y negated (``mirrored``)."""
        texture = material.normal_map
        assert texture is not None

        def make() -> np.ndarray:
            n = texture.astype(F32) * F32(2.0 / 255.0) - F32(1.0)
            n[..., :2] *= F32(material.normal_scale)
            if mirrored:
                n[..., 1] = -n[..., 1]
            n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), F32(1e-6))
            return (n + F32(1.0)) * F32(0.5)

        return self._bitmap(("normals", id(texture), material.normal_scale, mirrored), make, "bilinear")

    def bsdf(self, material: Material, mirrored: bool = False, tint: bool = False) -> dict:
        """The BSDF dict of ``material`` (``mirrored``: for faces whose UVs are mirrored, which
        matters only to normal maps; see :func:`mirrored_faces`; ``tint``: for a mesh with
        vertex colours, which then multiply every colour of the material, see
        :mod:`.vertex_tint`)."""
        roughness = self._channel(material, 1, material.roughness)
        if material.transmittance is not None or material.transmission is not None:
            surface: dict = {
                "type": "blendbsdf",
                "weight": 0.5,
                "reflect": self._sides(material, 2.0, tint),
                "transmit": {
                    "type": "principledthin",
                    "base_color": self._transmitted(material, tint),
                    "diff_trans": 2.0,
                    "spec_trans": 0.0,
                    "roughness": roughness,
                },
            }
        elif material.double_sided:
            surface = self._sides(material, tint=tint)
        else:
            surface = self._reflector(material, tint=tint)
        if material.normal_map is not None:
            # outside twosided: the back side is then shaded in the perturbed frame, mirrored
            surface = {"type": "normalmap", "normalmap": self._normals(material, mirrored), "bsdf": surface}
        cut = opacity(material)
        if cut is None:
            return surface
        if isinstance(cut, float):
            mask: Any = {"type": "uniform", "value": cut}
        else:
            mask = self._bitmap(("opacity", id(material.albedo), alpha_threshold(material)), lambda: cut, "nearest")
        return {"type": "mask", "opacity": mask, "bsdf": surface}
