"""The ``procedural`` plant library: ten species grown from a seed, standing in for the paper's
ten Megascans assets (Table 1), built the way game artists build plants: alpha-tested leaf,
frond and blade cards on a shared RGBA atlas with a label texture at the same UVs, opaque tube
stems, and (boxwood) dense solid leaf geometry.

Every species fits, at ``scale = 1``, in a cylinder of radius :data:`agrisim.scene.model.PLANT_FIT_RADIUS` and height
:data:`agrisim.scene.model.PLANT_FIT_HEIGHT` above the soil (plant frame: origin at the centre of the soil surface, z up).
The same seed gives identical arrays.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.interfaces import PlantSpecies
from agrisim.plugins.sensors import nir
from agrisim.scene import colour
from agrisim.scene.model import (
    PLANT_FIT_HEIGHT,
    PLANT_FIT_RADIUS,
    Material,
    Mesh,
    Plant,
)

from .growing import LEAF, Look
from .optics import leaf_nir, translucency
from .species import LOOKS, SPECIES, Grown
from .textures import Atlas, srgb_to_linear

SOIL_DEPTH = 0.012
"""How far stems and bulbs may reach into the soil, m."""


class ProceduralPlantOptions(Options):
    """Options of the procedural species."""

    scale: float = Field(1.0, ge=0.2, le=3.0)
    """Uniform size factor. At 1 every species fits in a 0.28 m radius x 0.40 m cylinder above
    the soil (the cameras' 0.5 m hemisphere leaves room); larger plants may reach the cameras."""
    density: float = Field(1.0, ge=0.25, le=2.0)
    """Multiplies the number of leaves, fronds, blades and flowers (1 = the species' natural
    density; boxwood at 1 has ~7500 solid leaves)."""
    texture_size: int | None = Field(None, ge=256, le=4096)
    """Side of the species' texture atlas in pixels; None uses the species' default (512 or
    1024). Shapes are resolution independent; only the detail changes."""


class ProceduralSpecies(PlantSpecies):
    """One species of the library; ``build(seed)`` grows a plant."""

    species: str = ""

    def __init__(self, options: ProceduralPlantOptions | None = None, **_context: object) -> None:
        super().__init__(options if options is not None else ProceduralPlantOptions())

    def build(self, seed: int) -> Plant:
        return grow(self.species, seed, self.options)


def grow(species: str, seed: int, options: ProceduralPlantOptions | None = None) -> Plant:
    """Grow ``species`` from ``seed`` (deterministic)."""
    if species not in SPECIES:
        raise KeyError(f"unknown procedural species {species!r}; available: {', '.join(SPECIES)}")
    opts = options or ProceduralPlantOptions()
    grower, default_size, _ = SPECIES[species]
    size = int(opts.texture_size or default_size)
    root = np.random.SeedSequence([int(seed) % (1 << 64), 0x9E3779B9])
    geo_ss, tex_ss, tint_ss = root.spawn(3)  # (the first two as they were before tints)
    look = LOOKS[species]
    grown: Grown = grower(np.random.default_rng(geo_ss), np.random.default_rng(tex_ss), size, float(opts.density), look)
    b = grown.builder
    # keep every plant within the camera-safe cylinder at scale 1 (shrink if a seed grew big)
    rmax, _zmin, zmax = b.bounds()
    fit = min(1.0, PLANT_FIT_RADIUS / rmax, PLANT_FIT_HEIGHT / zmax)
    b.transform(fit * float(opts.scale))
    # never deeper into the soil than SOIL_DEPTH (at any scale)
    for v in b.vertices:
        np.maximum(v[:, 2], -SOIL_DEPTH, out=v[:, 2])
    _palest(grown.atlas, look)
    rough_map, roughness = grown.atlas.metallic_roughness(look.roughness)
    cards = Material(
        f"{species}_cards",
        color=(1.0, 1.0, 1.0, 1.0),
        albedo=grown.atlas.rgba,
        labels=grown.atlas.labels,
        alpha_mode="MASK",
        alpha_cutoff=0.5,
        double_sided=True,
        roughness=roughness,
        metallic_roughness=rough_map,
        transmittance=translucency(look.leaf),
        normal_map=grown.atlas.normals if grown.atlas.relief else None,
        back_color=look.back_color,
        back_roughness=look.back_roughness,
        nir=leaf_nir(look.leaf),  # PROSPECT-D's, at 850 nm (flowers share the cards: the leaves')
    )
    stem_label = grown.labels.by_name("stem").id
    stems = Material(
        f"{species}_stem",
        color=(*srgb_to_linear(grown.stem_colour), 1.0),
        label=stem_label,
        alpha_mode="OPAQUE",
        double_sided=True,
        roughness=0.6,
        nir=nir.STEM,
    )
    wood = Material(
        f"{species}_wood",
        color=(*srgb_to_linear(grown.wood_colour or grown.stem_colour), 1.0),
        label=stem_label,
        alpha_mode="OPAQUE",
        double_sided=True,
        roughness=0.85,
        nir=nir.WOOD,
    )
    mesh = b.build(species, [cards, stems, wood])
    mesh.colors = _leaf_colours(mesh, look, np.random.default_rng(tint_ss))
    used = np.unique(mesh.face_material)  # drop materials no face uses (e.g. no wood)
    if len(used) < len(mesh.materials):
        remap = np.zeros(len(mesh.materials), np.int32)
        remap[used] = np.arange(len(used))
        mesh = dataclasses.replace(
            mesh, materials=[mesh.materials[i] for i in used], face_material=remap[mesh.face_material]
        )
    return Plant(name=species, mesh=mesh, labels=grown.labels, organs=len(grown.labels.labels) > 2, seed=int(seed))


def _palest(atlas: Atlas, look: Look) -> None:
    """Repaint the atlas' leaf texels as the palest leaf's (the painted colour over the mean
    tint): each leaf's vertex colour then darkens it by its own chlorophyll, the average leaf
    keeping the painted colour."""
    leaf = atlas.labels == LEAF
    linear = colour.srgb_to_linear(atlas.rgba[leaf][:, :3] / 255.0) / look.mean_tint()
    atlas.rgba[leaf, :3] = np.round(colour.linear_to_srgb(np.clip(linear, 0.0, 1.0)) * 255.0).astype(np.uint8)


def _leaf_colours(mesh: Mesh, look: Look, rng: np.random.Generator) -> np.ndarray | None:
    """Vertex colours giving every leaf (every leaf instance; stems and flowers have none) its
    own chlorophyll; None for a plant without leaf instances."""
    inst = mesh.face_instance
    if inst is None or not inst.any():
        return None
    tints = np.vstack([np.ones((1, 3)), look.leaf_tints(int(inst.max()), rng)])
    colours = np.ones((len(mesh.vertices), 3), np.float32)
    # a leaf's vertices are its own (the builder never shares them between items)
    colours[mesh.faces.reshape(-1)] = np.repeat(tints[inst], 3, axis=0)
    return colours


def _species_class(name: str) -> type[ProceduralSpecies]:
    cls = type(f"Procedural_{name}", (ProceduralSpecies,), {"species": name, "__doc__": SPECIES[name][2]})
    cls.__module__ = __name__
    return cls


#: one PlantSpecies subclass per species, ``factory(options)``
SPECIES_CLASSES: dict[str, type[ProceduralSpecies]] = {name: _species_class(name) for name in SPECIES}


@hookimpl
def agrisim_plants() -> list[BackendSpec]:
    return [
        BackendSpec(
            name=name,
            factory=SPECIES_CLASSES[name],
            description=SPECIES[name][2],
            options_model=ProceduralPlantOptions,
            limits="procedural stand-in for the paper's Megascans asset of the same name",
        )
        for name in SPECIES
    ]
