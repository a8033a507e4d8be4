"""User plant assets in, ground-truth plants out.

:func:`load_plant` reads a plant asset (glTF 2.0 ``.gltf``/``.glb``, or ``.obj`` with its ``.mtl``
and texture images) into an :class:`agrisim.scene.model.Plant`; :func:`export_glb` writes any
:class:`agrisim.scene.model.Mesh` as a binary glTF that carries everything agrisim needs to read it back
exactly (albedo with alpha and alpha settings, the label texture, the label table).

Frames
------
* glTF is y-up (spec); agrisim is z-up. Reading maps a point ``(x, y, z)`` of the asset to
  ``(x, -z, y)`` (a +90 deg rotation about x, as Blender's importer does); :func:`export_glb` maps
  ``(x, y, z)`` to ``(x, z, -y)``. Both are exact (only sign flips and swaps).
* OBJ has no up axis; most exporters (Blender, Maya, Quixel) write y-up, so OBJ is read as y-up
  too. ``up="z"`` reads either format as z-up (no rotation).
* Node transforms of glTF scene graphs are applied (a transform with negative determinant
  flips the triangles' winding, as the spec says), so the result is one mesh in the asset's frame.
* Then, unless ``place=False``, the plant is moved into the *plant frame*: lowest point at
  z = 0, the bounding box centred on x = y = 0 (origin at the centre of the soil surface).

Materials and opacity
---------------------
* glTF: ``baseColorTexture`` (RGBA) and ``baseColorFactor``, ``alphaMode`` OPAQUE/MASK/BLEND,
  ``alphaCutoff`` (default 0.5) and ``doubleSided`` (default false) are honoured as written;
  ``KHR_texture_transform`` on the base colour texture is baked into the UVs;
  ``KHR_materials_pbrSpecularGlossiness`` diffuse textures are read when there is no base colour.
  For path tracers: ``roughnessFactor``/``metallicFactor`` and ``metallicRoughnessTexture``,
  ``normalTexture`` (and its scale) and ``KHR_materials_diffuse_transmission`` (a fraction f
  of the diffuse light goes through in its own colour: factor and colour, and their textures;
  the reflected albedo keeps 1 - f). These textures must use the base colour's UV set and
  transform (agrisim keeps one per material); a file that does not is refused.
  Draco/meshopt-compressed or basisu-textured files are refused with a clear message.
* OBJ + MTL: ``map_Kd`` is the albedo (``Kd`` is its colour when there is none; with a texture,
  ``Kd`` is ignored, as Blender does); a ``map_Kd`` image whose alpha is not all opaque cuts the
  card: alpha mode MASK, cutoff 0.5. ``map_d`` gives the opacity (the image's alpha channel if it
  has one, else its luminance; ``-imfchan`` is honoured) and also means MASK. ``d`` < 1 sets the
  colour's alpha and BLEND. ``Tr`` is ignored (exporters disagree on its sign). ``-o``/``-s``
  texture options are baked into the UVs. OBJ materials are double-sided (leaf cards are).
* ``alpha_cutoff=`` overrides the cutoff of every MASK/BLEND material.

Labels (first that applies)
---------------------------
1. ``label_texture=PNG``: a texture at the albedo's UVs (and of the albedo's size). Either label
   ids (8-bit grey, 16-bit grey < 256, or a palette image whose indices are the ids, as PASCAL
   VOC masks) named by ``label_names={id: name}``, or flat label *colours*, as the paper's GIMP
   textures (black = background; each other colour one label, named ``label_names["#rrggbb"]``
   or after the paper's colours: green leaf, blue flower_white, red flower_purple).
2. ``material_labels={"Leaf*": "leaf", "Bark": "stem", "Pot": "background"}``: material-name
   patterns (``fnmatch``, first match wins) to organ names; organs get ids 1, 2, ... in the order
   they first appear among the values; "background" is id 0. Every material must match a pattern
   and every pattern a material.
3. An agrisim GLB's own label textures / constant labels and label table (see :func:`export_glb`).
4. Otherwise every triangle is label 1, "plant".

agrisim's GLB
-------------
Standard glTF 2.0 (any viewer shows it), plus ``extras``:
``asset.extras.agrisim = {"format": 1, "labels": [{"id", "name", "color"}, ...]}``; per material
``extras.agrisim = {"label": <constant id>, "label_texture": <texture index>, "alpha_cutoff": c}``
(the label texture is an 8-bit grey PNG of ids with a NEAREST sampler); per primitive
``extras.agrisim = {"face_instance": <accessor of uint16 per triangle>}`` when the mesh has leaf
instances. One primitive per run of consecutive triangles with the same material, all sharing one
vertex array, so vertices, triangles (and their order), UVs, textures, alpha settings and labels
read back identical (positions are float32 in glTF: exact for float32 vertices, <= 0.1 um off at
1 m otherwise). Only when materials alternate in many short runs are triangles grouped by material.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Literal

import numpy as np
from PIL import Image

from agrisim.plugins.formats.asset_reading import (
    AssetError,
    RawMesh,
    check_scale,
    decode_image,
    label_ids_plain,
    locate,
    open_asset,
    plant_frame_offset,
    read_bytes_of,
    unit_hint,
    y_up_to_z_up,
)
from agrisim.plugins.formats.gltf import read_gltf
from agrisim.plugins.formats.obj import read_obj
from agrisim.scene.model import Label, LabelTable, Material, Mesh, Plant
from agrisim.scene.palette import BACKGROUND, PALETTE, PAPER

__all__ = ["AssetError", "FORMATS", "MAX_SIZE", "load_plant"]

FORMATS = (".glb", ".gltf", ".obj")
"""File suffixes :func:`load_plant` reads."""

MAX_SIZE = 3.0
"""Largest sane plant, m (longest side of its bounding box)."""

_MORE_COLORS = [
    (255, 255, 0), (0, 255, 255), (255, 0, 255), (255, 128, 0), (128, 255, 0), (0, 128, 255),
    (255, 0, 128), (128, 128, 255), (255, 128, 128), (128, 255, 128), (160, 82, 45), (255, 255, 255),
]  # fmt: skip

_MAX_LABEL_COLOURS = 64


# The steps of reading an asset in order (read, orient, scale, labels, place, check), each a call or two.
def load_plant(
    path: str | os.PathLike[str],
    *,
    label_texture: str | os.PathLike[str] | None = None,
    label_names: Mapping[int | str, str] | None = None,
    material_labels: Mapping[str, str] | None = None,
    alpha_cutoff: float | None = None,
    name: str | None = None,
    up: Literal["y", "z"] | None = None,
    scale: float = 1.0,
    place: bool = True,
    max_size: float = MAX_SIZE,
    root: str | os.PathLike[str] | None = None,
) -> Plant:
    """Read a plant asset (``.glb``, ``.gltf``, ``.obj`` + ``.mtl``) as a :class:`Plant`.

    Args:
        path: the asset. With ``root``, a relative path is taken inside ``root``.
        label_texture: a PNG of label ids or label colours at the albedo's UVs (module doc).
        label_names: names of the label texture's ids (``{2: "stem"}``) or colours
            (``{"#00ff00": "leaf"}``).
        material_labels: material-name pattern -> organ name (module doc).
        alpha_cutoff: cutoff of every MASK/BLEND material instead of the file's.
        name: the plant's name (default: the file's stem).
        up: the asset's up axis, ``"y"`` (default for glTF, by its spec, and for OBJ) or ``"z"``.
        scale: multiplies the coordinates (``0.01`` for an asset in centimetres).
        place: move into the plant frame (lowest point at z = 0, centred in x/y).
        max_size: refuse a plant whose bounding box is longer than this, m.
        root: if given, the asset and every file it refers to must lie inside this directory
            (``..`` and symlinks out of it are refused).

    Raises:
        AssetError: (a :class:`UserError`) naming the file and the problem.
    """
    shown, root_dir, real, suffix = open_asset(path, root, FORMATS, "plant mesh")
    if alpha_cutoff is not None and not (isinstance(alpha_cutoff, (int, float)) and 0.0 <= alpha_cutoff <= 1.0):
        raise AssetError(f"{shown}: alpha_cutoff must be within 0..1, got {alpha_cutoff!r}")
    check_scale(scale, shown)
    if up not in (None, "y", "z"):
        raise AssetError(f"{shown}: up must be 'y' or 'z', got {up!r}")
    if label_names is not None and label_texture is None:
        raise AssetError(f"{shown}: label names apply to a label texture, and none was given")
    if label_texture is not None and material_labels is not None:
        raise AssetError(f"{shown}: give either a label texture or material labels, not both")

    if suffix == ".obj":
        raw = read_obj(real, shown, root_dir)
    else:
        raw = read_gltf(real, shown, root_dir)

    # Frame: asset -> z-up, metres.
    v = raw.positions
    if (up or "y") == "y":
        v = y_up_to_z_up(v)
    if scale != 1.0:
        v = v * float(scale)
    _check_geometry(shown, v, raw.faces)

    # Labels.
    if label_texture is not None:
        materials, table = _labels_from_texture(raw, shown, label_texture, label_names, root_dir)
    elif material_labels is not None:
        materials, table = _labels_from_materials(raw, shown, material_labels)
    elif raw.labels is not None:
        materials, table = raw.materials, raw.labels
    else:
        materials = [dataclasses.replace(m, labels=None, label=1) for m in raw.materials]
        table = LabelTable([Label(0, "background", BACKGROUND), Label(1, "plant", PALETTE["plant"])])
    if alpha_cutoff is not None:
        materials = [
            dataclasses.replace(m, alpha_cutoff=float(alpha_cutoff)) if m.alpha_mode != "OPAQUE" else m
            for m in materials
        ]
    _check_uvs(shown, raw, materials)

    # Size and placement.
    used = v[np.unique(raw.faces)]
    lo, hi = used.min(axis=0), used.max(axis=0)
    size = float((hi - lo).max())
    if size > max_size:
        raise AssetError(
            f"{shown}: the plant is {size:.4g} m across, more than {max_size:g} m{unit_hint(size, max_size)}"
        )
    if place:
        v = v - plant_frame_offset(lo, hi)

    plant_name = name or Path(path).stem
    instances = raw.face_instance
    if instances is None and raw.labels is None:  # a plain file, not agrisim's own
        instances = leaf_pieces(v, raw.faces, materials, raw.face_material)
    try:
        mesh = Mesh(plant_name, v, raw.faces, materials, raw.face_material, raw.uvs, instances, raw.colors)
    except ValueError as e:  # anything the checks above missed
        raise AssetError(f"{shown}: {e}") from None
    organs = sum(1 for lab in table.labels if lab.id != 0) > 1
    return Plant(plant_name, mesh, table, organs=organs)


def leaf_pieces(
    vertices: np.ndarray, faces: np.ndarray, materials: list[Material], face_material: np.ndarray
) -> np.ndarray | None:
    """Leaf instances of a plain mesh file (no agrisim extras): each connected piece of surface
    is one, 1, 2, ... in the order of its first triangle; triangles of background materials (a
    pot, soil: label 0 throughout) are none (0). Pieces are joined across vertices that sit at the
    same position, as files split them at texture seams. None where there is no piece."""
    import trimesh

    if not len(faces):
        return None
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)  # seams: one vertex per position
    piece = trimesh.graph.connected_component_labels(mesh.face_adjacency, node_count=len(faces))
    background = np.array([m.label == 0 and (m.labels is None or not np.any(m.labels)) for m in materials])
    kept = ~background[face_material] if len(materials) else np.ones(len(faces), bool)
    if not kept.any():
        return None
    # numbered in the order of each piece's first kept triangle
    order = {int(p): i + 1 for i, p in enumerate(dict.fromkeys(piece[kept].tolist()))}
    if len(order) > 65535:
        return None  # more pieces than instance ids: a scan's triangle soup, not leaves
    instances = np.array([order.get(int(p), 0) for p in piece], np.uint16)
    instances[~kept] = 0
    return instances


# --------------------------------------------------------------------------------------------
# Labels
# --------------------------------------------------------------------------------------------


def _table(entries: list[tuple[int, str, tuple[int, int, int] | None]]) -> LabelTable:
    labels = [Label(0, "background", (0, 0, 0))]
    for k, (i, n, c) in enumerate(entries):
        labels.append(Label(i, n, c or PALETTE.get(n) or _MORE_COLORS[k % len(_MORE_COLORS)]))
    return LabelTable(labels)


def _labels_from_materials(
    raw: RawMesh, shown: str, material_labels: Mapping[str, str]
) -> tuple[list[Material], LabelTable]:
    if not isinstance(material_labels, Mapping) or not all(
        isinstance(k, str) and isinstance(v, str) and v for k, v in material_labels.items()
    ):
        raise AssetError(f"{shown}: material labels must map material names (or patterns) to organ names")
    organs = [o for o in dict.fromkeys(material_labels.values()) if o != "background"]
    ids = {o: i for i, o in enumerate(organs, 1)}
    ids["background"] = 0
    if len(organs) > 255:
        raise AssetError(f"{shown}: at most 255 organ labels, got {len(organs)}")
    used = np.zeros(len(raw.materials), bool)
    used[np.unique(raw.face_material)] = True
    names = [m.name for m in raw.materials]
    matched: set[str] = set()
    out, missing = [], []
    for i, mat in enumerate(raw.materials):
        pattern = next((p for p in material_labels if fnmatch.fnmatchcase(mat.name, p)), None)
        if pattern is None:
            if used[i]:
                missing.append(mat.name)
            out.append(dataclasses.replace(mat, labels=None, label=0))
            continue
        matched.add(pattern)
        out.append(dataclasses.replace(mat, labels=None, label=ids[material_labels[pattern]]))
    unknown = [p for p in material_labels if p not in matched]
    if unknown:
        raise AssetError(
            f"{shown}: material labels {unknown} match no material; its materials are {sorted(set(names))}"
        )
    if missing:
        raise AssetError(
            f"{shown}: materials {sorted(set(missing))} have no label; give a label for each (patterns allowed)"
        )
    return out, _table([(ids[o], o, None) for o in organs])


def _labels_from_texture(
    raw: RawMesh,
    shown: str,
    label_texture: str | os.PathLike[str],
    label_names: Mapping[int | str, str] | None,
    root: Path | None,
) -> tuple[list[Material], LabelTable]:
    lshown = str(label_texture)
    real = locate(Path(label_texture), root, lshown, base=root)
    img = decode_image(read_bytes_of(real, lshown), lshown)
    ids, entries = _label_ids(img, lshown, label_names or {})
    if not any(i != 0 for i, _, _ in entries):
        raise AssetError(f"{lshown}: the label texture holds only background (0); it labels nothing as plant")
    out = []
    for mat in raw.materials:
        if mat.albedo is not None and mat.albedo.shape[:2] != ids.shape:
            h, w = mat.albedo.shape[:2]
            raise AssetError(
                f"{lshown}: label texture is {ids.shape[1]}x{ids.shape[0]} but the albedo of material "
                f"'{mat.name}' in {shown} is {w}x{h}; they must match texel for texel"
            )
        out.append(dataclasses.replace(mat, labels=ids, label=0))
    return out, _table(entries)


def _label_ids(
    img: Image.Image, shown: str, names: Mapping[int | str, str]
) -> tuple[np.ndarray, list[tuple[int, str, tuple[int, int, int] | None]]]:
    """Label ids of a label texture and its (id, name, colour) entries (module doc)."""
    colour_mode = False
    ids: np.ndarray
    if img.mode in ("L", "LA", "P", "1", "I;16", "I;16B", "I;16L", "I"):
        ids = label_ids_plain(img, shown)
    elif img.mode in ("RGB", "RGBA"):
        rgb = np.asarray(img.convert("RGB"))
        if np.array_equal(rgb[..., 0], rgb[..., 1]) and np.array_equal(rgb[..., 0], rgb[..., 2]):
            ids = rgb[..., 0].copy()
        else:
            colour_mode = True
    else:
        raise AssetError(
            f"{shown}: a label texture must be an image of label ids (grey or palette) or of flat label colours, not mode {img.mode}"
        )

    if not colour_mode:
        present = [int(i) for i in np.flatnonzero(np.bincount(ids.ravel(), minlength=256)) if i != 0]
        named = [int(k) for k in names if isinstance(k, int)]
        all_ids = sorted(set(present) | {i for i in named if 0 < i < 256})
        palette = None
        raw_palette = img.getpalette() if img.mode == "P" else None
        if raw_palette:
            palette = np.asarray(raw_palette[: 256 * 3], np.uint8).reshape(-1, 3)
        entries: list[tuple[int, str, tuple[int, int, int] | None]] = []
        for i in all_ids:
            default = "plant" if all_ids == [1] else f"label_{i}"
            colour = None
            if palette is not None and i < len(palette):
                r, g, b = (int(c) for c in palette[i])
                colour = (r, g, b)
            entries.append((i, str(names.get(i, default)), colour))
        return ids, entries

    flat = rgb.reshape(-1, 3)
    code = (flat[:, 0].astype(np.int64) << 16) | (flat[:, 1].astype(np.int64) << 8) | flat[:, 2]
    colours, inverse, counts = np.unique(code, return_inverse=True, return_counts=True)
    if len(colours) > _MAX_LABEL_COLOURS:
        raise AssetError(
            f"{shown}: label texture has {len(colours)} distinct colours, too many for flat labels "
            "(a photo, or a smoothed or JPEG-compressed texture?); use one flat colour or one id per label"
        )
    non_black = [(int(-counts[k]), int(colours[k]), k) for k in range(len(colours)) if colours[k] != 0]
    non_black.sort()
    lut = np.zeros(len(colours), np.uint8)
    by_colour = {v: k for k, v in PAPER.items()}
    lower = {str(k).lower(): v for k, v in names.items() if isinstance(k, str)}
    entries = []
    for new_id, (_, code_k, k) in enumerate(non_black, 1):
        colour = ((code_k >> 16) & 255, (code_k >> 8) & 255, code_k & 255)
        hexname = "#{:02x}{:02x}{:02x}".format(*colour)
        default = "plant" if len(non_black) == 1 else by_colour.get(colour, f"label_{hexname[1:]}")
        lut[k] = new_id
        entries.append((new_id, lower.get(hexname, default), colour))
    return lut[inverse.ravel()].reshape(rgb.shape[:2]), entries


# --------------------------------------------------------------------------------------------
# Checks, files, images
# --------------------------------------------------------------------------------------------


def _check_geometry(shown: str, v: np.ndarray, faces: np.ndarray) -> None:
    bad = ~np.all(np.isfinite(v), axis=1)
    if bad.any():
        raise AssetError(
            f"{shown}: {int(bad.sum())} vertices are NaN or infinite (the first is vertex {int(np.argmax(bad))})"
        )
    if len(faces) == 0:
        raise AssetError(f"{shown}: no triangles")
    a, b, c = (v[faces[:, i]] for i in range(3))
    with np.errstate(over="ignore", invalid="ignore"):  # absurd sizes are refused later, by size
        area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if not np.any(area > 0):
        raise AssetError(f"{shown}: every triangle is degenerate (zero area)")


def _check_uvs(shown: str, raw: RawMesh, materials: list[Material]) -> None:
    for i, mat in enumerate(materials):
        if mat.albedo is None and mat.labels is None:
            continue
        corners = raw.faces[raw.face_material == i]
        if len(corners) == 0:
            continue
        missing = ~raw.has_uv[corners].all(axis=1)
        if missing.any():
            tex = raw.texture_names[i] if i < len(raw.texture_names) else None
            what = f"texture '{tex}'" if tex and mat.albedo is not None else "a label texture"
            raise AssetError(
                f"{shown}: material '{mat.name}' uses {what} but {int(missing.sum())} of its "
                f"{len(corners)} triangles have no UVs (texture coordinates)"
            )
