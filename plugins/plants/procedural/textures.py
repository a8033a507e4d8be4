"""Texture atlases for procedural plants: RGBA albedo (alpha carries the shape) plus a label
texture at the same texels.

A species asks its :class:`Atlas` for rectangular tiles and paints each with a *painter*: a
function of the tile's card coordinates that returns coverage (0..1, the antialiased shape),
linear-ish RGB (0..1) and a label id for every texel. Every texel of a tile gets a non-zero label
(the organ of the card, or of the nearest organ drawn on it), exactly like an artist's flat
segmentation texture: with opacity ignored (``repopa``) the whole card is labelled.

Card coordinates of a tile (see :meth:`Tile.uv`): ``t`` in [-1, 1] across the card (left to
right), ``s`` in [0, 1] along it (base at the bottom of the tile, tip at the top). The corner
coordinates map to the *centres* of the tile's corner texels, so nearest lookups never reach a
neighbouring tile, whatever the float rounding of the UVs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from agrisim.scene import colour

#: painter(X, Y, px, rng) -> (coverage H x W float, rgb H x W x 3 float, labels H x W uint8) or
#: those and relief (H x W float: the height of the surface toward the card's front, the
#: leaf's upper side, in card lengths: veins in grooves are negative).
#: X = t * aspect / 2 (across, card-length units), Y = s (along), px = size of a texel in those units.
Painter = Callable[[np.ndarray, np.ndarray, float, np.random.Generator], tuple[np.ndarray, ...]]

FLAT = np.array([128, 128, 255], np.uint8)
"""A normal map's texel for an unperturbed normal."""

PAD = 2  # texels between tiles


@dataclass(frozen=True)
class Tile:
    """A rectangle of the atlas: rows r0..r0+h-1, columns c0..c0+w-1 of an H x W image."""

    r0: int
    c0: int
    h: int
    w: int
    H: int
    W: int

    @property
    def aspect(self) -> float:
        """Width / length of the card the tile is drawn for."""
        return (self.w - 1) / (self.h - 1)

    def uv(self, t: np.ndarray, s: np.ndarray) -> np.ndarray:
        """glTF UVs (K x 2) of card coordinates ``t`` (across, -1..1) and ``s`` (along, 0..1)."""
        t = np.asarray(t, float)
        s = np.asarray(s, float)
        u = (self.c0 + 0.5 + (t + 1.0) * 0.5 * (self.w - 1)) / self.W
        v = (self.r0 + 0.5 + (1.0 - s) * (self.h - 1)) / self.H
        return np.stack([u, v], axis=-1)

    def rect(self) -> np.ndarray:
        return np.array([self.r0, self.c0, self.h, self.w], float)


def tile_uv(rects: np.ndarray, H: int, W: int, t: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Vectorised :meth:`Tile.uv` for many cards: ``rects`` (N x 4: r0, c0, h, w) broadcast
    against ``t`` and ``s`` of shape (N, ...)."""
    extra = (slice(None),) + (None,) * (np.ndim(t) - 1)
    r0, c0, h, w = (rects[:, i][extra] for i in range(4))
    u = (c0 + 0.5 + (t + 1.0) * 0.5 * (w - 1)) / W
    v = (r0 + 0.5 + (1.0 - s) * (h - 1)) / H
    return np.stack([u, v], axis=-1)


class Atlas:
    """A square RGBA + label atlas filled by a shelf packer."""

    def __init__(self, size: int) -> None:
        self.size = int(size)
        self.rgba = np.zeros((self.size, self.size, 4), np.uint8)
        self.labels = np.zeros((self.size, self.size), np.uint8)
        self.normals = np.broadcast_to(FLAT, (self.size, self.size, 3)).copy()
        """Tangent-space normal map (glTF's convention) of the painters' relief."""
        self.relief = False
        """Whether any painter gave relief (else no normal map is needed)."""
        self.rougher = np.ones((self.size, self.size), np.float32)
        """Per texel, how many times rougher than the surface's own roughness: veins, in their
        grooves, are matte."""
        self._row = 0  # top of the current shelf
        self._col = 0
        self._shelf = 0  # height of the current shelf

    def tile(self, height: float, width: float) -> Tile:
        """Allocate a cell of ``height`` x ``width`` (fractions of the atlas size); the tile is
        the cell less a :data:`PAD` margin, so cells whose fractions sum to at most 1 fit at any
        atlas size."""
        ch = int(np.floor(height * self.size))
        cw = int(np.floor(width * self.size))
        if self._col + cw > self.size:
            self._row += self._shelf
            self._col, self._shelf = 0, 0
        if self._row + ch > self.size or cw > self.size or min(ch, cw) - PAD < 8:
            raise ValueError(f"atlas of {self.size} px is full or too small (cell {ch} x {cw})")
        t = Tile(self._row + PAD // 2, self._col + PAD // 2, ch - PAD, cw - PAD, self.size, self.size)
        self._col += cw
        self._shelf = max(self._shelf, ch)
        return t

    def paint(self, tile: Tile, painter: Painter, rng: np.random.Generator) -> Tile:
        """Draw ``painter`` into ``tile``."""
        j = np.arange(tile.w)
        i = np.arange(tile.h)
        t = -1.0 + 2.0 * j / (tile.w - 1)
        s = 1.0 - i / (tile.h - 1)
        X = (t * tile.aspect * 0.5)[None, :] * np.ones((tile.h, 1))
        Y = s[:, None] * np.ones((1, tile.w))
        px = 1.0 / (tile.h - 1)
        cov, rgb, lab, *relief = painter(X, Y, px, rng)
        alpha = np.clip(np.rint(cov * 255.0), 0, 255).astype(np.uint8)
        rgb = np.clip(rgb, 0.0, 1.0)
        inside = alpha >= 128
        if inside.any():  # transparent texels take the shape's mean colour (no dark fringes)
            rgb = np.where(inside[..., None], rgb, rgb[inside].mean(axis=0))
        sl = (slice(tile.r0, tile.r0 + tile.h), slice(tile.c0, tile.c0 + tile.w))
        self.rgba[sl + (slice(0, 3),)] = np.rint(rgb * 255.0).astype(np.uint8)
        self.rgba[sl + (3,)] = alpha
        if np.any(lab == 0):
            raise ValueError("painters must label every texel of their tile")
        self.labels[sl] = lab
        if relief:
            self.normals[sl] = np.where(inside[..., None], normal_texels(relief[0], px), FLAT)
            self.rougher[sl] = np.where(inside, 1.0 + 0.6 * np.clip(-relief[0] / 0.0015, 0.0, 1.0), 1.0)
            self.relief = True
        return tile

    def metallic_roughness(self, roughness: float) -> tuple[np.ndarray, float]:
        """(glTF metallic-roughness texture, its roughness factor) of a surface of ``roughness``
        made rougher where :attr:`rougher` says: green is the roughness / the factor, blue (the
        metallic) 0."""
        factor = float(min(1.0, roughness * float(self.rougher.max())))
        texture = np.zeros((self.size, self.size, 3), np.uint8)
        texture[..., 0] = 255
        texture[..., 1] = np.clip(np.rint(self.rougher * (roughness / factor) * 255.0), 0, 255)
        return texture, factor


def normal_texels(height: np.ndarray, px: float) -> np.ndarray:
    """glTF normal-map texels (H x W x 3 uint8) of a height field on a tile whose texels are
    ``px`` apart (rows from the tip down, columns left to right): x along the columns (the
    direction u grows), y up the image (toward the tip), z out of the front."""
    dh_dx = np.gradient(height, px, axis=1)
    dh_dy = -np.gradient(height, px, axis=0)  # (rows run down the image, toward the base)
    n = np.stack([-dh_dx, -dh_dy, np.ones_like(height)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.clip(np.rint((n + 1.0) * 127.5), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------------------ helpers


def coverage(f: np.ndarray, px: float) -> np.ndarray:
    """Antialiased coverage of the shape ``f > 0`` (``f`` roughly a distance, card units)."""
    return np.clip(0.5 + f / px, 0.0, 1.0)


def value_noise(rng: np.random.Generator, shape: tuple[int, int], cells: int, octaves: int = 3) -> np.ndarray:
    """Smooth fractal noise in [0, 1] of ``shape`` (bilinear value noise, ``octaves`` octaves)."""
    h, w = shape
    out = np.zeros(shape)
    amp, total = 1.0, 0.0
    for o in range(octaves):
        c = cells * 2**o
        grid = rng.random((c + 1, c + 1))
        y = np.linspace(0, c, h, endpoint=False) if h > 1 else np.zeros(1)
        x = np.linspace(0, c, w, endpoint=False) if w > 1 else np.zeros(1)
        y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
        fy, fx = (y - y0)[:, None], (x - x0)[None, :]
        fy, fx = fy * fy * (3 - 2 * fy), fx * fx * (3 - 2 * fx)
        g00 = grid[y0][:, x0]
        g01 = grid[y0][:, x0 + 1]
        g10 = grid[y0 + 1][:, x0]
        g11 = grid[y0 + 1][:, x0 + 1]
        out += amp * ((g00 * (1 - fx) + g01 * fx) * (1 - fy) + (g10 * (1 - fx) + g11 * fx) * fy)
        total += amp
        amp *= 0.5
    return out / total


def mix(a: np.ndarray | tuple, b: np.ndarray | tuple, k: np.ndarray) -> np.ndarray:
    """Per-texel blend of colours ``a`` and ``b`` by ``k`` (H x W) -> H x W x 3."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    k = np.clip(k, 0.0, 1.0)[..., None]
    if a.ndim == 1:
        a = a[None, None, :]
    if b.ndim == 1:
        b = b[None, None, :]
    return a * (1 - k) + b * k


def line_mask(dist: np.ndarray, width: float | np.ndarray) -> np.ndarray:
    """Soft stroke of half-width ``width`` around ``dist == 0``."""
    return np.clip(1.0 - np.abs(dist) / np.maximum(width, 1e-9), 0.0, 1.0)


def veins(X: np.ndarray, Y: np.ndarray, spacing: float, slope: float, width: float, start: float = 0.0) -> np.ndarray:
    """Lateral veins leaving a midrib at ``X = 0`` toward the tip at ``slope`` (dY/d|X|)."""
    q = (Y - start - slope * np.abs(X)) / spacing
    return line_mask((q - np.round(q)) * spacing, width) * (Y > start)


def radial_veins(
    X: np.ndarray, Y: np.ndarray, cx: float, cy: float, count: int, width: float, phase: float = 0.0
) -> np.ndarray:
    """Veins radiating from (cx, cy) (palmate and peltate leaves)."""
    dx, dy = X - cx, Y - cy
    r = np.hypot(dx, dy)
    ang = np.arctan2(dy, dx) + phase
    k = ang * count / (2 * np.pi)
    d = (k - np.round(k)) * 2 * np.pi / count * r
    return line_mask(d, width) * np.clip(r / (4 * width + 1e-9), 0, 1)


def groove(mask: np.ndarray, depth: float | np.ndarray) -> np.ndarray:
    """Relief of a vein sunk into the upper side: a rounded groove ``depth`` deep (card
    lengths) where the stroke ``mask`` (0..1, as :func:`line_mask` draws it) is."""
    m = np.clip(mask, 0.0, 1.0)
    return -depth * m * m * (3 - 2 * m)


def tissue(rng: np.random.Generator, shape: tuple[int, int], depth: float = 0.0002) -> np.ndarray:
    """Relief of a leaf's surface between its veins: fine bumps ``depth`` deep (card lengths)."""
    return depth * (value_noise(rng, shape, 40, octaves=2) - 0.5)


def leaf_colour(
    X: np.ndarray,
    Y: np.ndarray,
    rng: np.random.Generator,
    base: tuple[float, float, float],
    light: tuple[float, float, float],
    dark: tuple[float, float, float],
    vein: np.ndarray | None = None,
    vein_colour: tuple[float, float, float] | None = None,
    noise_cells: int = 4,
    noise: float = 0.6,
) -> np.ndarray:
    """A leaf's RGB: base colour with blotchy light/dark variation, tip-to-base gradient and
    optional veins."""
    n = value_noise(rng, X.shape, noise_cells)
    rgb = mix(mix(dark, base, np.clip(2 * n, 0, 1)), light, np.clip(2 * n - 1, 0, 1) * noise)
    rgb *= (0.9 + 0.15 * Y)[..., None]
    if vein is not None and vein_colour is not None:
        rgb = mix(rgb, vein_colour, vein)
    fine = value_noise(rng, X.shape, 24, octaves=2)
    return rgb * (0.92 + 0.16 * fine)[..., None]


def srgb_to_linear(c: tuple[float, float, float]) -> tuple[float, float, float]:
    """A colour given in sRGB (0..1) in linear units (for ``Material.color``)."""
    return tuple(float(x) for x in colour.srgb_to_linear(c))  # type: ignore[return-value]
