"""Procedural textures of the lab: floor tiles, painted walls, ceiling tiles, metal, wood, pot,
soil, cabinet fronts, drums.

Pure numpy. Every texture is sRGB RGBA uint8 (opaque), at most 512 px a side, tileable where it
repeats (value noise on a periodic lattice), generated from a fixed internal seed (the lab looks
the same whatever the PCG seed; the seed moves the clutter, not the paint) and cached: the arrays
returned are shared and read-only.

Image layout follows glTF UVs (row 0 is the top of the image, ``v = 0``); each function says
what its image spans in the world.
"""

from __future__ import annotations

from functools import cache

import numpy as np

_SEED = 20240611


def _rng(*key: int) -> np.random.Generator:
    return np.random.default_rng([_SEED, *key])


def value_noise(height: int, width: int, cell: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth, tileable value noise in [0, 1]: random values on a periodic lattice every
    ``cell`` pixels, interpolated with a smoothstep."""
    gh, gw = max(1, round(height / cell)), max(1, round(width / cell))
    grid = rng.random((gh, gw))

    def axis(n: int, g: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = (np.arange(n) + 0.5) / n * g - 0.5
        i0 = np.floor(t).astype(np.int64)
        f = t - i0
        f = f * f * (3.0 - 2.0 * f)
        return i0 % g, (i0 + 1) % g, f

    r0, r1, fy = axis(height, gh)
    c0, c1, fx = axis(width, gw)
    fy, fx = fy[:, None], fx[None, :]
    top = grid[r0][:, c0] * (1 - fx) + grid[r0][:, c1] * fx
    bottom = grid[r1][:, c0] * (1 - fx) + grid[r1][:, c1] * fx
    return top * (1 - fy) + bottom * fy


def fbm(height: int, width: int, rng: np.random.Generator, cells: tuple[int, ...] = (64, 32, 16, 8, 4)) -> np.ndarray:
    """Fractal value noise (octaves halving in size and weight), normalised to [0, 1]."""
    total = np.zeros((height, width))
    weight = 1.0
    for cell in cells:
        total += weight * value_noise(height, width, cell, rng)
        weight *= 0.5
    lo, hi = total.min(), total.max()
    return (total - lo) / max(hi - lo, 1e-12)


def _finish(rgb: np.ndarray) -> np.ndarray:
    """Float sRGB (H x W x 3, 0..1) -> read-only opaque RGBA uint8."""
    h, w = rgb.shape[:2]
    out = np.empty((h, w, 4), np.uint8)
    out[..., :3] = np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)
    out[..., 3] = 255
    out.setflags(write=False)
    return out


def _tint(shade: np.ndarray, color: tuple[float, float, float]) -> np.ndarray:
    return shade[..., None] * np.asarray(color, float)[None, None, :]


@cache
def floor_tiles() -> np.ndarray:
    """512 x 512 spanning 2.4 x 2.4 m: 4 x 4 speckled vinyl tiles of 0.6 m with grout lines."""
    n, tiles = 512, 4
    rng = _rng(1)
    shade = 1.0 + 0.05 * (fbm(n, n, rng) - 0.5) + 0.05 * (rng.random((n, n)) - 0.5)
    step = n // tiles
    jitter = 1.0 + 0.04 * (rng.random((tiles, tiles)) - 0.5)
    shade *= np.kron(jitter, np.ones((step, step)))
    speck = rng.random((n, n))
    shade[speck > 0.985] *= 0.75
    shade[speck < 0.01] *= 1.08
    scuff = fbm(n, n, rng, cells=(128, 64, 32))
    shade *= 1.0 - 0.06 * np.clip((scuff - 0.7) / 0.3, 0, 1)
    rgb = _tint(shade, (0.74, 0.73, 0.69))
    lines = (np.arange(n) % step) < 2
    rgb[lines, :, :] = (0.42, 0.41, 0.39)
    rgb[:, lines, :] = (0.42, 0.41, 0.39)
    return _finish(rgb)


@cache
def wall_paint() -> np.ndarray:
    """512 rows x 256 cols spanning 3 m of height (top row at the ceiling) and 2 m along the
    wall: matt paint with roller texture, a dark skirting board in the bottom 0.12 m."""
    h, w = 512, 256
    rng = _rng(2)
    shade = 1.0 + 0.04 * (fbm(h, w, rng, cells=(128, 64, 32)) - 0.5) + 0.03 * (value_noise(h, w, 2, rng) - 0.5)
    rgb = _tint(shade, (0.86, 0.86, 0.82))
    skirting = int(round(h * (1 - 0.12 / 3.0)))
    rgb[skirting:] = _tint(1.0 + 0.05 * (rng.random((h - skirting, w)) - 0.5), (0.26, 0.26, 0.27))
    rgb[skirting : skirting + 2] = (0.18, 0.18, 0.19)
    return _finish(rgb)


@cache
def ceiling_tiles() -> np.ndarray:
    """256 x 256 spanning 1.2 x 1.2 m: 2 x 2 perforated acoustic tiles in a white T-bar grid."""
    n = 256
    rng = _rng(3)
    shade = 1.0 + 0.03 * (fbm(n, n, rng) - 0.5)
    pores = rng.random((n, n)) > 0.93
    shade[pores] *= 0.82
    rgb = _tint(shade, (0.88, 0.88, 0.86))
    grid = (np.arange(n) % (n // 2)) < 3
    rgb[grid, :, :] = (0.95, 0.95, 0.95)
    rgb[:, grid, :] = (0.95, 0.95, 0.95)
    return _finish(rgb)


@cache
def painted_metal(color: tuple[float, float, float], key: int = 0) -> np.ndarray:
    """256 x 256 spanning 1 x 1 m: powder-coated steel of ``color`` with faint brushing."""
    n = 256
    rng = _rng(4, key)
    brushed = value_noise(n, n, 1, rng)[:, :1] * np.ones((1, n))  # streaks along u
    shade = 1.0 + 0.06 * (fbm(n, n, rng) - 0.5) + 0.03 * (brushed - 0.5) + 0.02 * (rng.random((n, n)) - 0.5)
    return _finish(_tint(shade, color))


@cache
def laminate() -> np.ndarray:
    """256 x 256 spanning 0.5 x 0.5 m: a light grey bench laminate with fine speckle."""
    n = 256
    rng = _rng(5)
    shade = 1.0 + 0.04 * (fbm(n, n, rng, cells=(64, 16, 4)) - 0.5)
    shade[rng.random((n, n)) > 0.97] *= 0.85
    return _finish(_tint(shade, (0.80, 0.80, 0.78)))


@cache
def wood(key: int = 0) -> np.ndarray:
    """256 x 256 spanning 1 x 0.25 m (grain along u): rough pallet pine with knots."""
    n = 256
    rng = _rng(6, key)
    warp = fbm(n, n, rng, cells=(64, 32, 16))
    v = np.arange(n)[:, None] / n * np.ones((1, n))
    grain = 0.5 + 0.5 * np.sin(2 * np.pi * (v * 9.0 + 1.5 * warp))
    shade = 0.85 + 0.15 * grain**3 + 0.06 * (value_noise(n, n, 2, rng) - 0.5)
    shade *= 1.0 - 0.12 * fbm(n, n, rng, cells=(128, 64))  # weathering
    rows, cols = np.mgrid[0:n, 0:n]
    for _ in range(2):  # knots
        r, c, rad = rng.integers(0, n), rng.integers(0, n), rng.uniform(4, 9)
        dr = (rows - r + n // 2) % n - n // 2
        dc = (cols - c + n // 2) % n - n // 2
        d = np.hypot(dr, dc * 0.5)
        shade *= 1.0 - 0.35 * np.exp(-((d / rad) ** 2))
    return _finish(_tint(shade, (0.76, 0.61, 0.42)))


@cache
def terracotta() -> np.ndarray:
    """256 x 256: a clay pot's side, u around the pot, v from the rim (top row) to the base, with
    a thicker rim band over the top 18 %."""
    n = 256
    rng = _rng(7)
    shade = 1.0 + 0.08 * (fbm(n, n, rng) - 0.5) + 0.05 * (rng.random((n, n)) - 0.5)
    rim = int(0.18 * n)
    shade[:rim] *= 1.06
    shade[rim : rim + 3] *= 0.7
    shade[-4:] *= 0.85
    return _finish(_tint(shade, (0.72, 0.40, 0.25)))


@cache
def soil() -> np.ndarray:
    """256 x 256 spanning the soil disc's diameter: dark moist soil, crumbs and a few pebbles."""
    n = 256
    rng = _rng(8)
    shade = 0.8 + 0.4 * fbm(n, n, rng, cells=(32, 16, 8, 4, 2))
    crumbs = rng.random((n, n))
    shade[crumbs > 0.96] *= 1.35
    shade[crumbs < 0.05] *= 0.6
    rgb = _tint(shade, (0.27, 0.18, 0.11))
    rows, cols = np.mgrid[0:n, 0:n]
    for _ in range(14):
        r, c, rad = rng.uniform(0, n), rng.uniform(0, n), rng.uniform(1.5, 4.0)
        m = (rows - r) ** 2 + (cols - c) ** 2 < rad**2
        rgb[m] = np.asarray((0.55, 0.52, 0.48)) * rng.uniform(0.7, 1.1)
    return _finish(rgb)


@cache
def cabinet_front(color: tuple[float, float, float]) -> np.ndarray:
    """512 rows x 256 cols spanning a 1.9 m tall, 0.9 m wide cabinet front: two doors with a
    centre gap, frame, louvres, handles, a lock and a label card, a dark plinth."""
    h, w = 512, 256
    rng = _rng(9, int(sum(color) * 1000))
    shade = 1.0 + 0.05 * (fbm(h, w, rng) - 0.5) + 0.02 * (rng.random((h, w)) - 0.5)
    rgb = _tint(shade, color)
    dark = np.asarray(color) * 0.45
    frame = 6
    plinth = int(h * 0.95)
    rgb[:frame] = dark
    rgb[:, :frame] = dark
    rgb[:, -frame:] = dark
    rgb[plinth:] = (0.12, 0.12, 0.12)
    rgb[plinth - 2 : plinth] = dark
    mid = w // 2
    rgb[:plinth, mid - 2 : mid + 2] = (0.1, 0.1, 0.1)  # door gap
    for lo, hi in ((frame + 14, mid - 14), (mid + 14, w - frame - 14)):  # louvres, top and bottom
        for top in (40, plinth - 80):
            for k in range(6):
                r = top + 8 * k
                rgb[r : r + 3, lo:hi] = dark * 0.6
                rgb[r + 3 : r + 4, lo:hi] = np.minimum(np.asarray(color) * 1.2, 1.0)
    handle_top, handle_len = int(h * 0.42), 56
    for c in (mid - 16, mid + 10):  # handles: chrome bars with a highlight
        rgb[handle_top : handle_top + handle_len, c : c + 6] = (0.72, 0.73, 0.75)
        rgb[handle_top : handle_top + handle_len, c + 1 : c + 2] = (0.93, 0.93, 0.95)
        rgb[handle_top : handle_top + handle_len, c + 5 : c + 6] = (0.35, 0.35, 0.37)
    rows, cols = np.mgrid[0:h, 0:w]
    lock = (rows - (handle_top - 16)) ** 2 + (cols - (mid + 13)) ** 2 < 16
    rgb[lock] = (0.8, 0.7, 0.3)
    r0, c0 = 100, frame + 20  # label card with "text"
    rgb[r0 : r0 + 36, c0 : c0 + 60] = (0.95, 0.95, 0.92)
    for k in range(4):
        length = int(rng.integers(25, 52))
        rgb[r0 + 6 + 7 * k : r0 + 9 + 7 * k, c0 + 5 : c0 + 5 + length] = (0.1, 0.1, 0.1)
    return _finish(rgb)


@cache
def drum_side(color: tuple[float, float, float]) -> np.ndarray:
    """256 rows x 512 cols: a steel drum's side, u once around (1.82 m), v from the top chime
    (row 0) to the bottom (0.88 m): two rolling hoops, chimes, scratches, a hazard label."""
    h, w = 256, 512
    rng = _rng(10, int(sum(color) * 1000))
    shade = 1.0 + 0.08 * (fbm(h, w, rng) - 0.5) + 0.03 * (rng.random((h, w)) - 0.5)
    rgb = _tint(shade, color)
    col = np.asarray(color)
    for centre in (h // 3, 2 * h // 3):  # rolling hoops: a highlight above, a shadow below
        for d in range(-5, 6):
            rgb[centre + d] = np.clip(rgb[centre + d] * (1.0 + 0.05 * -d), 0, 1)
        rgb[centre - 6] *= 0.8
        rgb[centre + 6] *= 0.6
    rgb[:6] = col * 0.55
    rgb[-6:] = col * 0.55
    scratches = rng.random((h, w)) > 0.995
    rgb[scratches] = (0.6, 0.6, 0.62)
    rust = fbm(h, w, rng, cells=(32, 16, 8)) > 0.88
    rgb[rust] = rgb[rust] * 0.5 + np.asarray((0.45, 0.22, 0.08)) * 0.5
    r0, c0, lh, lw = 100, 60, 52, 120  # label between the hoops
    rgb[r0 : r0 + lh, c0 : c0 + lw] = (0.95, 0.95, 0.93)
    for k in range(5):
        length = int(rng.integers(40, 80))
        rgb[r0 + 6 + 9 * k : r0 + 10 + 9 * k, c0 + 42 : c0 + 42 + length] = (0.08, 0.08, 0.08)
    rows, cols = np.mgrid[0:h, 0:w]
    diamond = np.abs(rows - (r0 + lh // 2)) + np.abs(cols - (c0 + 20)) < 18
    rgb[diamond] = (0.95, 0.45, 0.05)
    return _finish(rgb)


@cache
def drum_lid(color: tuple[float, float, float]) -> np.ndarray:
    """128 x 128 spanning the lid's diameter: pressed rings and two bungs."""
    n = 128
    rng = _rng(11, int(sum(color) * 1000))
    shade = 1.0 + 0.06 * (fbm(n, n, rng, cells=(32, 16, 8)) - 0.5)
    rgb = _tint(shade, color)
    rows, cols = np.mgrid[0:n, 0:n]
    r = np.hypot(rows - n / 2 + 0.5, cols - n / 2 + 0.5) / (n / 2)
    rgb[(r > 0.9) & (r < 0.95)] *= 0.6
    rgb[(r > 0.7) & (r < 0.72)] *= 0.8
    for dr, dc, rad in ((-0.45, 0.2, 0.12), (0.5, -0.3, 0.07)):
        rr = np.hypot(rows / (n / 2) - 1 - dr, cols / (n / 2) - 1 - dc)
        rgb[rr < rad] = (0.55, 0.55, 0.57)
        rgb[(rr >= rad) & (rr < rad + 0.03)] *= 0.5
    return _finish(rgb)
