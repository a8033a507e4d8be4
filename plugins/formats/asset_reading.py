"""What every plant-asset reader produces (:class:`RawMesh`) and the file access they share:
paths confined to a root directory, bytes read with errors that name the file, images decoded."""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from agrisim.errors import UserError
from agrisim.scene.model import LabelTable, Material


class AssetError(UserError):
    """A plant asset cannot be read: the message names the file and the problem."""


@dataclass
class RawMesh:
    """A mesh as read, before frames, labels and checks (positions in the asset's frame)."""

    positions: np.ndarray  # (N, 3) float64
    faces: np.ndarray  # (M, 3) int64
    face_material: np.ndarray  # (M,) int64
    materials: list[Material]
    uvs: np.ndarray | None  # (N, 2) float32, glTF convention
    has_uv: np.ndarray  # (N,) bool: did the file give this vertex a UV?
    texture_names: list[str | None] = field(default_factory=list)  # per material, for messages
    face_instance: np.ndarray | None = None
    colors: np.ndarray | None = None  # (N, 3) float32 linear vertex colours (glTF COLOR_0)
    labels: LabelTable | None = None  # an agrisim file's own label table


def resolve_root(root: str | os.PathLike[str] | None) -> Path | None:
    if root is None:
        return None
    real = Path(root).expanduser().resolve()
    if not real.is_dir():
        raise AssetError(f"{root}: the asset root is not a directory")
    return real


def locate(path: Path, root: Path | None, shown: str, base: Path | None, must_exist: bool = True) -> Path:
    """The real path of ``path`` (relative to ``base``), refusing escapes out of ``root``."""
    path = path.expanduser()
    full = path if path.is_absolute() or base is None else base / path
    if root is not None:
        lexical = Path(os.path.normpath(full if full.is_absolute() else Path.cwd() / full))
        if not lexical.is_relative_to(root):
            raise AssetError(
                f"{shown}: outside the asset root {root} (paths may not leave it with '..' or absolute paths)"
            )
        real = lexical.resolve()
        if not real.is_relative_to(root):
            raise AssetError(f"{shown}: a symlink out of the asset root {root} (to {real})")
    else:
        real = full.resolve()
    if must_exist:
        if not real.exists():
            raise AssetError(f"{shown}: no such file")
        if real.is_dir():
            raise AssetError(f"{shown}: is a directory, not a file")
    return real


def open_asset(
    path: str | os.PathLike[str], root: str | os.PathLike[str] | None, formats: tuple[str, ...], what: str
) -> tuple[str, Path | None, Path, str]:
    """A plant asset's name as given (for messages), the resolved asset root (None: none), its
    real path (inside that root if one is given) and its lower-case suffix; refuses a suffix outside ``formats`` (``what``: the kind of
    file, for the message)."""
    shown = str(path)
    root_dir = resolve_root(root)
    real = locate(Path(path), root_dir, shown, base=root_dir)
    suffix = Path(path).suffix.lower() or real.suffix.lower()
    if suffix not in formats:
        raise AssetError(f"{shown}: not a {what} format agrisim reads (use {', '.join(formats)})")
    return shown, root_dir, real, suffix


def check_scale(scale: object, shown: str) -> None:
    """Refuse an asset ``scale`` that is not a positive, finite number."""
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise AssetError(f"{shown}: scale must be a positive number, got {scale!r}")


def read_bytes_of(path: Path, shown: str) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise AssetError(f"{shown}: no such file") from None
    except IsADirectoryError:
        raise AssetError(f"{shown}: is a directory, not a file") from None
    except OSError as e:
        raise AssetError(f"{shown}: cannot be read ({e.strerror or e})") from None


def decode_image(data: bytes, shown: str) -> Image.Image:
    try:
        img = Image.open(io.BytesIO(data))
        img.load()
    except UnidentifiedImageError:
        raise AssetError(f"{shown}: not an image Pillow can read") from None
    except (OSError, SyntaxError, ValueError) as e:
        raise AssetError(f"{shown}: not an image Pillow can read ({e})") from None
    if img.width < 1 or img.height < 1:
        raise AssetError(f"{shown}: an empty image")
    return img


def rgba_array(img: Image.Image) -> np.ndarray:
    """H x W x 4 uint8 of any Pillow image (16-bit grey scaled to 8 bits)."""
    if img.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        a = np.asarray(img).astype(np.float64)
        a = (
            a / 257.0
            if img.mode.startswith("I") and a.size and a.max() > 255
            else a * (255.0 if img.mode == "F" else 1.0)
        )
        g = np.clip(np.rint(a), 0, 255).astype(np.uint8)
        return np.dstack([g, g, g, np.full_like(g, 255)])
    return np.asarray(img.convert("RGBA")).copy()


def label_ids_plain(img: Image.Image, shown: str) -> np.ndarray:
    """The label ids of a label-id image (8-bit grey, 16-bit grey below 256, 1-bit, or palette indices)."""
    if img.mode in ("I;16", "I;16B", "I;16L", "I"):
        a = np.asarray(img)
        if a.size and (a.max() > 255 or a.min() < 0):
            raise AssetError(f"{shown}: label ids must be within 0..255, found {int(a.max())}")
        return a.astype(np.uint8)
    if img.mode == "1":
        return np.asarray(img).astype(np.uint8)
    if img.mode == "LA":
        return np.asarray(img.getchannel("L")).copy()
    return np.asarray(img).astype(np.uint8, copy=True)  # L, P (palette indices are the ids)


def y_up_to_z_up(v: np.ndarray) -> np.ndarray:
    """Points of a y-up asset (glTF's convention) in agrisim's z-up frame: ``(x, y, z)`` ->
    ``(x, -z, y)``, a +90 deg rotation about x as Blender's importer does (exact: only swaps and
    a sign; ``+ 0.0`` keeps negative zeros out)."""
    return np.column_stack([v[:, 0], -v[:, 2], v[:, 1]]) + 0.0


def plant_frame_offset(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """What to subtract from an asset's points (bounding box ``lo``..``hi``) to put it in the
    plant frame: lowest point at z = 0, the bounding box centred on x = y = 0."""
    return np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])


def unit_hint(size: float, max_size: float) -> str:
    """A hint that a plant ``size`` m across (more than ``max_size``) is in other units."""
    for factor, unit in ((0.01, "centimetres"), (0.001, "millimetres"), (0.0254, "inches")):
        if 0.02 <= size * factor <= max_size:
            return f" (is it in {unit}? then load it with scale={factor:g})"
    return " (check its units; scale= rescales it)"
