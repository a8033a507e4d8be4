"""glTF materials as agrisim materials: the base colour, its alpha mode and cutoff exactly as
written (agrisim's cut-outs are a step at the cutoff, for MASK and BLEND alike), the maps path
tracers use, KHR_materials_diffuse_transmission, and agrisim's own label textures, labels and
translucency from ``extras``.

pygltflib gives the material's fields; their meaning for agrisim is here: trimesh's reader
turns ``baseColorFactor`` into 8-bit colours and knows neither ``KHR_texture_transform``,
other texture coordinate sets, diffuse transmission nor label textures.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from agrisim.plugins.formats.asset_reading import label_ids_plain, rgba_array
from agrisim.plugins.formats.gltf_document import GltfDocument, get
from agrisim.scene.colour import linear_to_srgb, srgb_to_linear
from agrisim.scene.model import Material

Placement = tuple[int, tuple[float, ...] | None]
"""A texture's TEXCOORD set and its KHR_texture_transform (offset u, v, rotation, scale u, v) or None."""

ReadMaterial = tuple[Material, int, tuple[float, ...] | None, str | None]
"""(material, TEXCOORD set of its textures, KHR_texture_transform or None, texture name)."""

Rgba = tuple[float, float, float, float]


def default_material() -> ReadMaterial:
    """The glTF spec's default material, for primitives that name none."""
    return Material("default", (1.0, 1.0, 1.0, 1.0), double_sided=False, label=1), 0, None, None


def read_material(doc: GltfDocument, index: int) -> ReadMaterial:
    """Material ``index`` of ``doc`` as an agrisim material, with the texture placement its UVs
    need and its texture's name (for messages)."""
    m = doc.item("materials", index)
    mname = str(m.name or f"material_{index}")
    pbr = m.pbrMetallicRoughness
    factor = pbr.baseColorFactor if pbr is not None else [1.0, 1.0, 1.0, 1.0]
    tex_info = pbr.baseColorTexture if pbr is not None else None
    spec_gloss = get(m.extensions, "KHR_materials_pbrSpecularGlossiness")
    if tex_info is None and isinstance(spec_gloss, dict):
        tex_info = spec_gloss.get("diffuseTexture")
        factor = spec_gloss.get("diffuseFactor", factor)
    if not (isinstance(factor, list) and len(factor) == 4 and all(isinstance(c, (int, float)) for c in factor)):
        raise doc.error(f"material '{mname}' has a malformed baseColorFactor")
    mode = m.alphaMode
    if mode not in ("OPAQUE", "MASK", "BLEND"):
        raise doc.error(f"material '{mname}' has an unknown alphaMode {mode!r}")
    extras = get(m.extras, "agrisim") if doc.agrisim is not None else None
    cutoff = 0.5 if m.alphaCutoff is None else m.alphaCutoff
    if isinstance(extras, dict) and "alpha_cutoff" in extras:
        cutoff = extras["alpha_cutoff"]
    if not (isinstance(cutoff, (int, float)) and 0.0 <= cutoff <= 1.0):
        raise doc.error(f"material '{mname}' has alphaCutoff {cutoff!r}, outside 0..1")

    albedo, texcoord, transform, tex_name = None, 0, None, None
    if tex_info is not None:
        img, tex_name = doc.texture_image(get(tex_info, "index"))
        albedo = rgba_array(img)
        texcoord, transform = _texture_placement(tex_info)
    maps = _MapReader(doc, mname, None if tex_info is None else (texcoord, transform))

    labels, label = None, 1
    if isinstance(extras, dict):
        label = extras.get("label", 1)
        if not isinstance(label, int) or not 0 <= label <= 255:
            raise doc.error(f"material '{mname}' has a malformed agrisim label {label!r}")
        if "label_texture" in extras:
            img, lname = doc.texture_image(extras["label_texture"])
            if img.mode not in ("L", "P", "I;16", "I", "1"):
                raise doc.error(f"material '{mname}': label texture {lname} is not a single-channel image of label ids")
            labels = label_ids_plain(img, f"{doc.shown}: label texture {lname}")
            if albedo is not None and labels.shape != albedo.shape[:2]:
                raise doc.error(
                    f"material '{mname}': label texture {lname} is {labels.shape[1]}x{labels.shape[0]} but its "
                    f"albedo is {albedo.shape[1]}x{albedo.shape[0]}; they must match texel for texel"
                )
            if tex_name is None:
                tex_name = lname
    color, roughness, metallic, transmittance = _look(pbr, factor, extras)
    albedo, color, transmission = _transmission(doc, m, extras, maps, albedo, color)
    normal = m.normalTexture
    normal_map = maps.rgb(normal, "normalTexture")
    scale = get(normal, "scale")
    normal_scale = float(1.0 if scale is None else scale) if normal_map is not None else 1.0
    if not (math.isfinite(normal_scale) and normal_scale >= 0.0):
        raise doc.error(f"material '{mname}' has normalTexture.scale {normal_scale!r}; it must be >= 0")
    if maps.placement is not None:
        texcoord, transform = maps.placement
    mat = Material(
        mname,
        color=color,
        albedo=albedo,
        labels=labels,
        label=label,
        alpha_mode=mode,
        alpha_cutoff=float(cutoff),
        double_sided=bool(m.doubleSided),
        roughness=roughness,
        metallic=metallic,
        transmittance=None if transmission is not None else transmittance,
        transmission=transmission,
        metallic_roughness=maps.rgb(get(pbr, "metallicRoughnessTexture"), "metallicRoughnessTexture"),
        normal_map=normal_map,
        normal_scale=normal_scale,
        **_back(extras),
    )
    return mat, texcoord, transform, tex_name


def _look(pbr: Any, factor: list[Any], extras: Any) -> tuple[Rgba, float, float, tuple[float, float, float] | None]:
    """(colour factor, roughness, metallic, transmittance) of a material: glTF's defaults
    (metallic and rough) where the file is silent; agrisim's own files carry their
    transmittance (per unit of albedo) in extras."""
    r, g, b, a = (float(c) for c in factor)
    rough, metal = get(pbr, "roughnessFactor"), get(pbr, "metallicFactor")
    roughness, metallic = _unit(1.0 if rough is None else rough), _unit(1.0 if metal is None else metal)
    transmittance = None
    if isinstance(extras, dict) and isinstance(extras.get("transmittance"), list):
        t = [max(float(x), 0.0) for x in extras["transmittance"][:3]]
        transmittance = (t[0], t[1], t[2]) if len(t) == 3 else None
    return (r, g, b, a), roughness, metallic, transmittance


def _back(extras: Any) -> dict[str, Any]:
    """The back side agrisim's own files keep in a material's extras (glTF has no such field):
    ``back_color`` (three factors) and ``back_roughness``; what is malformed is left out."""
    out: dict[str, Any] = {}
    if not isinstance(extras, dict):
        return out
    colour = extras.get("back_color")
    if isinstance(colour, list) and len(colour) == 3 and all(isinstance(c, int | float) for c in colour):
        values = tuple(float(c) for c in colour)
        if all(math.isfinite(c) and c >= 0.0 for c in values):
            out["back_color"] = values
    rough = extras.get("back_roughness")
    if isinstance(rough, int | float) and 0.0 <= float(rough) <= 1.0:
        out["back_roughness"] = float(rough)
    return out


def _transmission(
    doc: GltfDocument, m: Any, extras: Any, maps: _MapReader, albedo: np.ndarray | None, color: Rgba
) -> tuple[np.ndarray | None, Rgba, np.ndarray | None]:
    """(albedo, colour factor, transmission texture) under diffuse transmission.

    KHR_materials_diffuse_transmission mixes a diffuse reflector of the base colour and a
    diffuse transmitter of its own colour, a fraction f = factor x texture alpha going
    through: the reflected part becomes the albedo x (1 - f) (in the colour factor when f
    is constant, else texel by texel on the albedo's grid) and the transmitted colour f x
    colour factor x colour texture becomes agrisim's transmission texture. agrisim's own
    files keep theirs in extras (already split)."""
    if isinstance(extras, dict) and "transmission_texture" in extras:
        img, _ = doc.texture_image(extras["transmission_texture"])
        return albedo, color, np.asarray(img.convert("RGB")).copy()
    ext = get(m.extensions, "KHR_materials_diffuse_transmission")
    if not isinstance(ext, dict):
        return albedo, color, None
    f = _unit(ext.get("diffuseTransmissionFactor", 0.0))
    tint = [_unit(t) for t in (ext.get("diffuseTransmissionColorFactor") or [1.0, 1.0, 1.0])[:3]]
    f_tex = maps.rgba(ext.get("diffuseTransmissionTexture"), "diffuseTransmissionTexture")
    tint_tex = maps.rgba(ext.get("diffuseTransmissionColorTexture"), "diffuseTransmissionColorTexture")
    if f == 0.0:
        return albedo, color, None
    # the transmitted colour, linear, on the grid of whichever texture has one
    grid = next((t for t in (tint_tex, f_tex) if t is not None), np.zeros((1, 1, 4), np.uint8))
    f_map = f if f_tex is None else f * _resample(f_tex, grid.shape[:2])[..., 3:4] / 255.0
    through = f_map * np.asarray(tint) * (1.0 if tint_tex is None else srgb_to_linear(tint_tex[..., :3] / 255.0))
    transmission = _srgb8(np.broadcast_to(through, (*grid.shape[:2], 3)))
    if f_tex is None:
        kept = 1.0 - f
        color = (color[0] * kept, color[1] * kept, color[2] * kept, color[3])
    else:
        base = albedo if albedo is not None else np.full((*f_tex.shape[:2], 4), 255, np.uint8)
        keep = 1.0 - f * _resample(f_tex, base.shape[:2])[..., 3:4] / 255.0
        albedo = np.dstack([_srgb8(srgb_to_linear(base[..., :3] / 255.0) * keep), base[..., 3]])
    return albedo, color, transmission


def _unit(x: Any) -> float:
    return min(max(float(x), 0.0), 1.0)


def _texture_placement(info: Any) -> Placement:
    """(TEXCOORD set, KHR_texture_transform or None) of a texture reference (a pygltflib
    texture info, or the JSON object of one inside an extension)."""
    texcoord, transform = int(get(info, "texCoord") or 0), None
    tt = get(info, "extensions", "KHR_texture_transform")
    if isinstance(tt, dict):
        texcoord = int(tt.get("texCoord", texcoord))
        off, rot, sc = tt.get("offset", [0.0, 0.0]), float(tt.get("rotation", 0.0)), tt.get("scale", [1.0, 1.0])
        if (off, rot, sc) != ([0.0, 0.0], 0.0, [1.0, 1.0]):
            transform = (float(off[0]), float(off[1]), rot, float(sc[0]), float(sc[1]))
    return texcoord, transform


def _srgb8(linear: np.ndarray) -> np.ndarray:
    return np.round(linear_to_srgb(np.clip(linear, 0.0, 1.0)) * 255.0).astype(np.uint8)


def _resample(texture: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``texture`` sampled nearest at the texel centres of an image of ``shape``."""
    rows = (np.arange(shape[0]) + 0.5) * texture.shape[0] // shape[0]
    cols = (np.arange(shape[1]) + 0.5) * texture.shape[1] // shape[1]
    return texture[rows.astype(np.int64)[:, None], cols.astype(np.int64)[None, :]]


class _MapReader:
    """A material's textures other than the base colour, which must share its UV placement
    (agrisim keeps one UV set per mesh); the first one fixes it when there is no base colour
    texture."""

    def __init__(self, doc: GltfDocument, material: str, placement: Placement | None) -> None:
        self.doc, self.material, self.placement = doc, material, placement

    def rgba(self, info: Any, what: str) -> np.ndarray | None:
        if not (isinstance(info, dict) or dataclasses.is_dataclass(info)):
            return None
        placement = _texture_placement(info)
        if self.placement is None:
            self.placement = placement
        elif placement != self.placement:
            raise self.doc.error(
                f"material '{self.material}': its {what} uses other texture coordinates (set or transform) than its "
                "other textures; agrisim reads one UV set per material: re-export with one"
            )
        img, _ = self.doc.texture_image(get(info, "index"))
        return rgba_array(img)

    def rgb(self, info: Any, what: str) -> np.ndarray | None:
        texture = self.rgba(info, what)
        return None if texture is None else np.ascontiguousarray(texture[..., :3])
