"""A PyHelios ``Context`` as agrisim's plant asset: one textured triangle mesh with organ labels
and leaf instances.

Helios keeps every primitive apart (its own vertices, UVs, texture file, colour and material), so
the conversion is a handful of batched queries and array operations:

* **Geometry.** Triangles stay triangles; patches (four vertices) are split into two. Vertices are
  not shared between primitives, as in Helios, so UVs and materials never need seams.
* **UVs.** Helios's v grows upwards with (0, 0) at the image's bottom-left (its solid-fraction
  raster flips the image rows); agrisim follows glTF, v down from the top-left, so ``v -> 1 - v``.
  Helios clamps UVs to the image while agrisim wraps, so UVs are kept just inside [0, 1).
* **Textures** are read once per file into RGBA uint8 with Pillow, which also expands the palette
  PNGs with a ``tRNS`` transparency entry (several Helios leaves) and gives JPEGs full alpha.
  Textures with an alpha channel become alpha-tested (``MASK``) materials whose cutoff is Helios's
  own: a texel is solid when its alpha is at least 250 (Helios's ``readPNGAlpha``), so agrisim's
  cut-out leaves have exactly the area Helios's radiation and leaf-area models use.
* **Colours.** Untextured primitives (stems, petioles, most flowers) get their Helios RGB colour,
  read as sRGB, as the material's constant colour. A texture whose colour Helios overrides keeps
  only its alpha (white albedo times the colour).
* **Double-sided** is Helios's material ``twosided`` flag (0 = one-sided).
* **Organs** come from PlantArchitecture's organ queries; see :func:`organ_labels`.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from agrisim.plugins.sensors import nir
from agrisim.scene.colour import srgb_to_linear
from agrisim.scene.model import LEAF_ROUGHNESS, LEAF_TRANSMITTANCE, Label, LabelTable, Material, Mesh
from agrisim.scene.palette import PALETTE

#: The organ labels of every Helios plant. Ids are fixed across models and ages, so a dataset of
#: several Helios plants uses one id per organ; a plant's table lists only the organs it has.
#: Colours are agrisim's one palette (the paper's); "stem" is Helios's internodes.
ORGANS: tuple[Label, ...] = tuple(
    Label(i, name, PALETTE[name])
    for i, name in enumerate(("leaf", "stem", "petiole", "peduncle", "flower", "fruit"), 1)
)
ORGAN_IDS: dict[str, int] = {lab.name: lab.id for lab in ORGANS}

#: Thin organs that let light through like leaves (petals too, a little less green, but close)
TRANSLUCENT_ORGANS = ("leaf", "flower")


def _look(organ: str) -> dict:
    """Looks of an organ's material: translucent leaves and petals, rougher stems (path
    tracers), and its near-infrared reflectance (depth sensors, :mod:`agrisim.plugins.sensors.nir`)."""
    if organ in TRANSLUCENT_ORGANS:
        return {
            "roughness": LEAF_ROUGHNESS,
            "transmittance": LEAF_TRANSMITTANCE,
            "nir": nir.PETAL if organ == "flower" else nir.LEAF,
        }
    return {"roughness": 0.7, "nir": nir.STEM}


HELIOS_ALPHA_CUTOFF = 249.5 / 255.0
"""Alpha cutoff of Helios's leaf textures: Helios counts a texel as solid when its 8-bit alpha is
250 or more, so alpha 250/255 must pass and 249/255 must not."""

_UV_MAX = np.float32(1.0 - 2.0**-24)  # largest float32 below 1: clamp to the image, never wrap

PRIMITIVE_PATCH = 0
PRIMITIVE_TRIANGLE = 1


@dataclass
class Primitives:
    """The primitives of a Helios context as flat arrays (P primitives, V vertices in all)."""

    uuids: np.ndarray  # (P,) uint32
    vertices: np.ndarray  # (V, 3) float64, primitive after primitive
    first: np.ndarray  # (P,) index of each primitive's first vertex
    count: np.ndarray  # (P,) vertices per primitive: 3 (triangle) or 4 (patch)
    uvs: np.ndarray  # (V, 2) float32, glTF convention; 0 where the primitive has no texture
    textures: list[str]  # (P) texture file, "" for none
    colors: np.ndarray  # (P, 3) float Helios RGB (sRGB, 0..1)
    materials: list[str]  # (P) Helios material label

    def __len__(self) -> int:
        return len(self.uuids)


def fetch(ctx: Any, uuids: Sequence[int]) -> Primitives:
    """Read the primitives ``uuids`` of the Helios context ``ctx`` with batched queries."""
    uuids = [int(u) for u in uuids]
    P = len(uuids)
    if P == 0:
        none = np.zeros(0, np.int64)
        return Primitives(none.astype(np.uint32), np.zeros((0, 3)), none, none, np.zeros((0, 2), np.float32), [],
                          np.zeros((0, 3)), [])  # fmt: skip
    vdata, voffsets = ctx.getPrimitiveVertices(uuids)
    vertices = np.asarray(vdata, np.float64).reshape(-1, 3)
    voffsets = np.asarray(voffsets, np.int64)
    count = np.diff(voffsets) // 3
    first = voffsets[:-1] // 3
    bad = ~np.isin(count, (3, 4))
    if bad.any():
        types = np.asarray(ctx.getPrimitiveType([uuids[int(i)] for i in np.flatnonzero(bad)[:5]]))
        counts = sorted(set(count[bad].tolist()))
        raise ValueError(
            f"Helios primitives with {counts} vertices (types {types.tolist()}): only triangles and patches convert"
        )
    textures = list(ctx.getPrimitiveTextureFile(uuids))
    uvs = np.zeros((len(vertices), 2), np.float32)
    uvdata, uvoffsets = ctx.getPrimitiveTextureUV(uuids)
    uvdata = np.asarray(uvdata, np.float32).reshape(-1, 2)
    uvoffsets = np.asarray(uvoffsets, np.int64)
    if len(uvoffsets) == P + 1 and len(uvdata):
        n_uv = np.diff(uvoffsets) // 2
        with_uv = n_uv > 0
        if np.any(n_uv[with_uv] != count[with_uv]):
            raise ValueError("Helios primitives whose UV count differs from their vertex count")
        # the UVs come primitive after primitive, like the vertices: scatter them onto the vertices
        # of the primitives that have them
        vertex_has_uv = np.repeat(with_uv, count)
        uv = uvdata.copy()
        uv[:, 1] = 1.0 - uv[:, 1]  # Helios v up -> glTF v down
        uvs[vertex_has_uv] = np.clip(uv, 0.0, _UV_MAX)
    colors = np.asarray(ctx.getPrimitiveColor(uuids), np.float64).reshape(P, -1)[:, :3]
    materials = list(ctx.getPrimitiveMaterialLabel(uuids))
    return Primitives(np.asarray(uuids, np.uint32), vertices, first, count, uvs, textures, colors, materials)


# ------------------------------------------------------------------------------- organs


def organ_labels(plantarch: Any, ctx: Any, plant_id: int, prims: Primitives) -> tuple[np.ndarray, np.ndarray]:
    """Organ label id (uint8) and leaf instance id (uint16, 0 = none) of every primitive.

    PlantArchitecture answers which primitives are leaves, internodes (the ``stem`` label),
    petioles, peduncles, flowers and fruit. A Helios leaf object is one leaf blade (one leaflet of
    a compound leaf) *together with its stalk*: a tomato or bean leaflet is a textured blade plus
    an untextured tube in a petiole material. Those stalk triangles are labelled ``petiole`` and
    belong to no instance, so that every instance pixel is a leaf pixel. The stalk of a leaf
    object is its untextured part when the blade is textured; when nothing is textured, its part
    drawn in a material that stalks (internodes, petioles, peduncles) use. A leaf object drawn in
    one material only (asparagus's needles share the stem's) stays all leaf. Each leaf object is
    one instance, numbered from 1 in object-id order.
    """
    index = {int(u): i for i, u in enumerate(prims.uuids)}

    def rows(uuids: Sequence[int]) -> np.ndarray:
        return np.fromiter((index[u] for u in uuids if u in index), np.int64)

    # Primitives not named by any organ query (none in the library's models) count as stem.
    labels = np.full(len(prims), ORGAN_IDS["stem"], np.uint8)
    queries = (
        ("stem", plantarch.getAllInternodeUUIDs),
        ("petiole", plantarch.getAllPetioleUUIDs),
        ("peduncle", plantarch.getAllPeduncleUUIDs),
        ("flower", plantarch.getAllFlowerUUIDs),
        ("fruit", plantarch.getAllFruitUUIDs),
        ("leaf", plantarch.getAllLeafUUIDs),
    )
    for organ, query in queries:
        labels[rows(query())] = ORGAN_IDS[organ]

    materials = np.asarray(prims.materials, dtype=object)
    stalk = labels != ORGAN_IDS["leaf"]
    stalk_materials = set(materials[stalk].tolist())
    is_stalk_material = np.fromiter((m in stalk_materials for m in prims.materials), bool, len(prims))

    textured = np.fromiter((bool(t) for t in prims.textures), bool, len(prims))

    instances = np.zeros(len(prims), np.uint16)
    objects = sorted(int(o) for o in plantarch.getPlantLeafObjectIDs(plant_id))
    if len(objects) > np.iinfo(np.uint16).max:
        raise ValueError(f"{len(objects)} leaves: more than 65535 leaf instances")
    for k, obj in enumerate(objects, start=1):
        r = rows(ctx.getObjectPrimitiveUUIDs(obj))
        r = r[labels[r] == ORGAN_IDS["leaf"]]
        stalk_part = ~textured[r] if textured[r].any() else is_stalk_material[r]
        if stalk_part.all():  # drawn only in stalk materials (asparagus): all blade
            stalk_part[:] = False
        labels[r[stalk_part]] = ORGAN_IDS["petiole"]
        instances[r[~stalk_part]] = k
    return labels, instances


def label_table(labels: np.ndarray) -> LabelTable:
    """The organ labels present in ``labels`` (plus background), with their fixed ids."""
    present = set(np.unique(labels).tolist())
    return LabelTable([Label(0, "background", (0, 0, 0))] + [lab for lab in ORGANS if lab.id in present])


# ------------------------------------------------------------------------------- textures


@functools.lru_cache(maxsize=64)
def _texture(path: str, mtime_ns: int) -> tuple[np.ndarray, bool]:
    from PIL import Image

    with Image.open(path) as im:
        has_alpha = im.mode in ("RGBA", "LA", "PA", "RGBa", "La") or "transparency" in im.info
        rgba = np.asarray(im.convert("RGBA"), dtype=np.uint8).copy()
    rgba.flags.writeable = False  # shared between plants built in this process
    return rgba, has_alpha


def load_texture(path: str) -> tuple[np.ndarray, bool]:
    """``(rgba, has_alpha)``: the image as H x W x 4 uint8 sRGB + alpha (read-only, cached per
    file and modification time) and whether the file carries transparency."""
    return _texture(path, os.stat(path).st_mtime_ns)


# ------------------------------------------------------------------------------- the mesh


def to_mesh(
    ctx: Any,
    prims: Primitives,
    labels: np.ndarray,
    instances: np.ndarray,
    name: str,
) -> Mesh:
    """One :class:`Mesh` of the primitives, with one material per distinct texture, solid
    colour, organ label and Helios material flags (colour override, two-sided)."""
    tri = prims.count == 3
    # triangles: (first, first+1, first+2); patches: two triangles (0, 1, 2), (0, 2, 3)
    faces = np.concatenate(
        [
            prims.first[tri, None] + np.array([0, 1, 2]),
            prims.first[~tri, None] + np.array([0, 1, 2]),
            prims.first[~tri, None] + np.array([0, 2, 3]),
        ]
    )
    face_prim = np.concatenate([np.flatnonzero(tri), np.flatnonzero(~tri), np.flatnonzero(~tri)])
    order = np.argsort(face_prim, kind="stable")  # keep Helios's primitive order
    faces, face_prim = faces[order], face_prim[order]

    # material keys: texture, label, the Helios material's flags and (for solid colours) the colour
    tex_names, tex_index = np.unique(np.asarray(prims.textures, dtype=object).astype(str), return_inverse=True)
    mat_names, mat_index = np.unique(np.asarray(prims.materials, dtype=object).astype(str), return_inverse=True)
    overridden = np.array([bool(ctx.isMaterialTextureColorOverridden(m)) for m in mat_names.tolist()], bool)[mat_index]
    twosided = np.array([int(ctx.getMaterialTwosidedFlag(m)) != 0 for m in mat_names.tolist()], bool)[mat_index]
    uses_colour = (tex_names[tex_index] == "") | overridden
    colour_key = np.where(uses_colour[:, None], np.round(prims.colors * 10000).astype(np.int64), -1)
    keys = np.column_stack([tex_index, labels, overridden, twosided, colour_key]).astype(np.int64)
    unique_keys, prim_material = np.unique(keys, axis=0, return_inverse=True)
    prim_material = prim_material.reshape(-1)

    model = name.split(":")[-1]
    materials: list[Material] = []
    for k, (t, label, override, double_sided, *_rgb) in enumerate(unique_keys.tolist()):
        first = int(np.flatnonzero(prim_material == k)[0])
        texture = str(tex_names[t])
        organ = next(lab.name for lab in ORGANS if lab.id == label)
        colour = (*(float(c) for c in srgb_to_linear(prims.colors[first])), 1.0)
        double_sided = bool(double_sided)
        if texture:
            rgba, has_alpha = load_texture(texture)
            if override:  # Helios draws the colour, cut by the texture's alpha
                white = np.full_like(rgba, 255)
                white[..., 3] = rgba[..., 3]
                rgba = white
            else:
                colour = (1.0, 1.0, 1.0, 1.0)
            stem = os.path.splitext(os.path.basename(texture))[0]
            materials.append(
                Material(
                    f"{model}_{organ}_{stem}_{k}",
                    color=colour,
                    albedo=rgba,
                    label=int(label),
                    alpha_mode="MASK" if has_alpha else "OPAQUE",
                    alpha_cutoff=HELIOS_ALPHA_CUTOFF,
                    double_sided=double_sided,
                    **_look(organ),
                )
            )
        else:
            materials.append(
                Material(
                    f"{model}_{organ}_{k}",
                    color=colour,
                    label=int(label),
                    alpha_mode="OPAQUE",
                    double_sided=double_sided,
                    **_look(organ),
                )
            )
    return Mesh(
        name,
        prims.vertices,
        faces,
        materials,
        prim_material[face_prim].astype(np.int32),
        prims.uvs,
        instances[face_prim],
    )
