"""Procedural leaf, frond, blade, petal and flower textures (painters for :class:`.textures.Atlas`).

Every painter returns (coverage, rgb, labels) over a tile whose card coordinates are ``X``
(across, card-length units, centred) and ``Y`` (along, 0 at the base, 1 at the tip), see
:meth:`.textures.Atlas.paint`. Shapes are drawn with antialiased edges into coverage (alpha);
every texel of the tile is labelled (the card's organ), as a flat segmentation texture would be.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from agrisim.scene.colour import linear_to_srgb, srgb_to_linear

from .textures import coverage, groove, leaf_colour, line_mask, mix, radial_veins, tissue, value_noise, veins

Shape = Callable[[np.ndarray], np.ndarray]  # Y -> half-width as a fraction of the tile's half-width


def _full(X: np.ndarray, label: int) -> np.ndarray:
    return np.full(X.shape, label, np.uint8)


def _smooth(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


# --------------------------------------------------------------------- outlines (half-widths)


def ovate(peak: float = 0.4, power: float = 0.8) -> Shape:
    """Rounded leaf widest at ``peak`` of its length; ``power`` < 1 fattens it."""
    p = np.log(0.5) / np.log(peak)
    return lambda Y: np.sin(np.pi * np.clip(Y, 0, 1) ** p) ** power


def strap(base: float = 0.1, tip: float = 0.2) -> Shape:
    """Long parallel-sided leaf (amaryllis) narrowing at the base, rounded at the tip."""

    def f(Y: np.ndarray) -> np.ndarray:
        b = np.clip(Y / base, 0, 1) ** 0.5 * 0.6 + 0.4 * (Y > 0)
        t = np.sqrt(np.clip(1 - ((Y - (1 - tip)) / tip).clip(0) ** 2, 0, 1))
        return np.minimum(b, 1.0) * t * (0.88 + 0.12 * np.clip(1 - Y, 0, 1))

    return f


def serrate(shape: Shape, teeth: float, depth: float) -> Shape:
    """``shape`` with ``teeth`` saw teeth along its length, ``depth`` deep (fraction)."""
    return lambda Y: shape(Y) * (1 - depth * ((Y * teeth) % 1.0))


# --------------------------------------------------------------------------- leaf painters


def lamina(
    shape: Shape,
    base: tuple,
    light: tuple,
    dark: tuple,
    vein_colour: tuple,
    label: int,
    *,
    vein_spacing: float = 0.07,
    vein_slope: float = 0.8,
    midrib: float = 0.006,
    vein_width: float = 0.0025,
    vein_strength: float = 0.6,
    noise_cells: int = 4,
    parallel: float = 0.0,
    pattern: Callable | None = None,
    base_tint: tuple | None = None,
):
    """A simple leaf: outline ``shape`` (half-width fraction along its length), midrib,
    pinnate veins (or parallel veins with ``parallel`` > 0), blotchy colour."""

    def paint(X, Y, px, rng):
        half = X.max()
        hw = shape(Y) * half * 0.96
        cov = coverage(hw - np.abs(X), px) * (Y > 0.002) * (Y < 0.998)
        if parallel > 0:
            lateral = line_mask((X / parallel - np.round(X / parallel)) * parallel, vein_width) * 0.5
        else:
            lateral = veins(X, Y, vein_spacing, vein_slope, vein_width, start=0.03) * (np.abs(X) < 0.92 * hw)
        rib = midrib * (1.2 - 0.7 * Y)
        mid = line_mask(X, rib)
        v = np.maximum(lateral, mid) * vein_strength
        relief = groove(mid, 0.6 * rib) + groove(lateral, 0.5 * vein_width)
        rgb = leaf_colour(X, Y, rng, base, light, dark, v, vein_colour, noise_cells)
        if base_tint is not None:
            rgb = mix(rgb, base_tint, 0.6 * np.clip(1 - Y / 0.25, 0, 1))
        if pattern is not None:
            rgb = pattern(X, Y, hw, rgb, rng)
        rgb = rgb * (0.85 + 0.15 * _smooth(np.abs(X) / np.maximum(hw, 1e-6)))[..., None]  # darker margin
        return cov, rgb, _full(X, label), relief + tissue(rng, X.shape)

    return paint


def aglaonema_pattern(X, Y, hw, rgb, rng):
    """Chinese evergreen: silver feathered patches between the lateral veins."""
    q = (Y - 0.9 * np.abs(X)) / 0.06
    band = np.abs(q - np.round(q))  # 0 on veins, 0.5 between
    n = value_noise(rng, X.shape, 6)
    rel = np.abs(X) / np.maximum(hw, 1e-6)
    k = (
        _smooth((band - 0.12) / 0.2)
        * _smooth((n - 0.35) / 0.2)
        * _smooth((0.85 - rel) / 0.15)
        * _smooth((rel - 0.08) / 0.1)
    )
    return mix(rgb, (0.62, 0.7, 0.58), 0.85 * k)


def peltate(label: int, colours: dict):
    """Round peltate leaf (indian cress): petiole under the centre, pale veins radiating."""

    def paint(X, Y, px, rng):
        cx, cy = 0.0, 0.5
        dx, dy = X - cx, Y - cy
        r, th = np.hypot(dx, dy), np.arctan2(dx, dy)
        R = 0.47 * (1 + 0.025 * np.sin(7 * th + rng.uniform(0, 6.28)))
        cov = coverage(R - r, px)
        rays = radial_veins(X, Y, 0.015, 0.51, 9, 0.004, rng.uniform(0, 1))
        rgb = leaf_colour(X, Y, rng, colours["base"], colours["light"], colours["dark"], 0.8 * rays, colours["vein"], 3)
        rgb = mix(rgb, colours["light"], 0.4 * np.clip(1 - r / 0.08, 0, 1))
        return cov, rgb, _full(X, label), groove(rays, 0.0025) + tissue(rng, X.shape)

    return paint


def cordate(label: int, colours: dict):
    """Heart-shaped, coarsely toothed leaf (coltsfoot); the petiole meets the sinus, whose card
    coordinate is returned by :func:`cordate_anchor`."""

    def paint(X, Y, px, rng):
        dx, dy = X, Y - 0.5
        r, th = np.hypot(dx, dy), np.arctan2(dx, dy)
        edge = cordate_edge(th)
        cov = coverage(edge - r, px)
        ay = cordate_anchor()
        rays = radial_veins(X, Y, 0.0, ay, 11, 0.004, 0.5) * (Y > ay - 0.05)
        rgb = leaf_colour(X, Y, rng, colours["base"], colours["light"], colours["dark"], 0.7 * rays, colours["vein"], 4)
        return cov, rgb, _full(X, label), groove(rays, 0.0025) + tissue(rng, X.shape)

    return paint


def cordate_edge(th: np.ndarray) -> np.ndarray:
    tooth = np.abs(((th * 13 / (2 * np.pi)) % 1.0) - 0.5) * 2
    notch = 1 - 0.5 * np.exp(-(((np.abs(th) - np.pi) / 0.3) ** 2))
    return 0.48 * (0.95 + 0.05 * np.cos(th)) * notch * (1 - 0.03 * tooth)


def cordate_anchor() -> float:
    """``s`` of the sinus (where the petiole meets a cordate leaf)."""
    return float(0.5 - cordate_edge(np.array([np.pi]))[0] + 0.01)


def lobed(label: int, colours: dict, lobes: float, aspect_hint: float = 0.5):
    """Pinnately lobed leaf (bog marshcress): a large terminal lobe and alternate side lobes."""

    def paint(X, Y, px, rng):
        half = X.max()
        env = np.where(Y < 0.72, 0.45 + 0.55 * Y, np.sqrt(np.clip(1 - ((Y - 0.72) / 0.28) ** 2, 0, 1)))
        env = env * np.clip(Y / 0.06, 0, 1)
        off = np.where(X < 0, 0.5, 0.0)
        lob = 0.45 + 0.55 * np.abs(np.sin(np.pi * (lobes * Y / 0.72 + off))) ** 0.7
        lob = np.where(Y < 0.72, lob, 1.0)
        lob = np.maximum(lob, 0.12 / np.maximum(env, 1e-3))  # keep the rachis
        hw = np.clip(env * lob, 0, 1) * half * 0.96
        cov = coverage(hw - np.abs(X), px) * (Y < 0.998)
        mid, lateral = line_mask(X, 0.006), veins(X, Y, 0.72 / lobes / 2, 0.5, 0.002, 0.05)
        v = np.maximum(mid, lateral * 0.5) * 0.7
        rgb = leaf_colour(X, Y, rng, colours["base"], colours["light"], colours["dark"], v, colours["vein"], 3)
        rgb = mix(rgb, colours["tint"], 0.5 * np.clip(1 - Y / 0.3, 0, 1))
        return cov, rgb, _full(X, label), groove(mid, 0.0035) + groove(lateral, 0.001) + tissue(rng, X.shape)

    return paint


def ellipse_leaf(label: int, colours: dict, midrib: float = 0.03):
    """An ellipse filling its tile (boxwood leaves, hydrangea petals): solid polygons whose
    outline lies just inside it use it with (almost) nothing cut away."""

    def paint(X, Y, px, rng):
        a = X.max()
        e = np.sqrt((X / a) ** 2 + ((Y - 0.5) / 0.5) ** 2)
        cov = coverage((1 - e) * min(a, 0.5), px)
        mid = line_mask(X, midrib * a) * (np.abs(Y - 0.5) < 0.45)
        v = 0.5 * mid
        rgb = leaf_colour(X, Y, rng, colours["base"], colours["light"], colours["dark"], v, colours["vein"], 2, 0.8)
        if "rim" in colours:
            rgb = mix(rgb, colours["rim"], 0.7 * _smooth((e - 0.55) / 0.45))
        if "centre" in colours:
            rgb = mix(rgb, colours["centre"], 0.7 * _smooth((0.45 - e) / 0.45))
        return cov, rgb, _full(X, label), groove(mid, 0.6 * midrib * a) + tissue(rng, X.shape)

    return paint


# ------------------------------------------------------------------------------- ferns


def frond(
    label: int,
    colours: dict,
    *,
    pinnae: int,
    envelope: Shape,
    pinna_width: float,
    angle: float,
    stipe: float,
    lobes: float = 0.0,
    rachis: float = 0.006,
):
    """A pinnate fern frond: a rachis with alternate pinnae (``pinnae`` per side) whose
    lengths follow ``envelope``; ``pinna_width`` is a pinna's half-width as a fraction of the
    spacing (gaps between pinnae below 0.5), ``angle`` tilts them toward the tip, ``stipe``
    is the bare base; ``lobes`` > 0 cuts each pinna into pinnules (bipinnate look)."""

    def paint(X, Y, px, rng):
        half = X.max()
        sp = (1.0 - stipe) / pinnae
        ax = np.abs(X)
        Yp = Y - ax * np.tan(angle) - np.where(X < 0, 0.5 * sp, 0.0) - stipe
        k = np.clip(np.round(Yp / sp), 0, pinnae - 1)
        yk = stipe + k * sp + np.where(X < 0, 0.5 * sp, 0.0)
        d = (Yp - k * sp) * np.cos(angle)  # across the pinna
        length = envelope(np.clip((yk - stipe) / (1 - stipe), 0, 1)) * half * 0.97 / np.cos(angle)
        length = length * (yk < 0.995)
        ll = ax / np.cos(angle)
        rel = np.clip(ll / np.maximum(length, 1e-6), 0, 1)
        q = pinna_width * sp * np.sqrt(np.clip(1 - rel**2, 0, 1)) * (0.6 + 0.4 * np.clip(1 - rel, 0, 1))
        if lobes > 0:
            ps = np.maximum(length, 1e-6) / lobes
            q = q * (0.45 + 0.55 * np.abs(np.cos(np.pi * (ll - np.abs(d) * 0.8) / ps)) ** 0.6)
        f_pinna = np.minimum(q - np.abs(d), length - ll + 0.002)
        f_pinna = np.where(Yp > -0.5 * sp, f_pinna, -1.0)
        f_rachis = np.minimum(rachis * (1.1 - 0.6 * Y) - ax, 0.995 - Y)
        cov = coverage(np.maximum(f_pinna, f_rachis), px) * (Y > 0.002)
        n = value_noise(rng, X.shape, 5)
        rgb = mix(
            mix(colours["dark"], colours["base"], np.clip(2 * n, 0, 1)), colours["light"], np.clip(2 * n - 1, 0, 1)
        )
        rgb = mix(rgb, colours["light"], 0.35 * rel)  # lighter pinna tips
        vein = line_mask(d, 0.12 * pinna_width * sp) * (ll < length)
        rgb = mix(rgb, colours["vein"], 0.35 * vein)
        on_rachis = f_rachis > f_pinna
        rgb = np.where(on_rachis[..., None], np.asarray(colours["rachis"], float), rgb)
        fine = value_noise(rng, X.shape, 30, octaves=2)
        rgb = rgb * (0.9 + 0.2 * fine)[..., None]
        # a grooved rachis, and each pinna's midvein sunk into it
        relief = np.where(on_rachis, groove(line_mask(X, rachis * (1.1 - 0.6 * Y)), rachis * 0.5), groove(vein, 0.001))
        return cov, rgb, _full(X, label), relief + tissue(rng, X.shape, 0.0001)

    return paint


def grass_blades(label: int, colours: dict, blades: int, width: float):
    """Several fine grass blades fanning from the base of the card (basket grass)."""

    def paint(X, Y, px, rng):
        half = X.max()
        f = np.full(X.shape, -1.0)
        shade = np.zeros(X.shape)
        crease = np.zeros(X.shape)
        for i in range(blades):
            x0 = rng.uniform(-0.15, 0.15) * half
            lean = rng.uniform(-0.7, 0.7) * half
            curve = rng.uniform(-0.3, 0.3) * half
            length = rng.uniform(0.7, 0.99)
            w = width * rng.uniform(0.75, 1.25)
            cx = x0 + lean * Y + curve * Y**2
            rel = np.clip(Y / length, 0, 1)
            hw = w * (1 - rel) ** 0.45 * np.clip(Y / 0.03, 0.4, 1)
            fi = np.where(Y < length, hw - np.abs(X - cx), -1.0)
            better = fi > f
            shade = np.where(better, np.clip(0.5 + (X - cx) / np.maximum(2 * hw, 1e-6), 0, 1) + 0.15 * i, shade)
            crease = np.where(better, groove(line_mask(X - cx, 0.5 * hw), 0.4 * hw), crease)
            f = np.maximum(f, fi)
        cov = coverage(f, px) * (Y > 0.002)
        n = value_noise(rng, X.shape, 3)
        rgb = mix(
            mix(colours["dark"], colours["base"], np.clip(2 * n, 0, 1)), colours["light"], np.clip(2 * n - 1, 0, 1)
        )
        rgb = mix(rgb, colours["tip"], _smooth((Y - 0.6) / 0.4) * 0.7)
        rgb = rgb * (0.85 + 0.2 * (shade % 1.0))[..., None]
        return cov, rgb, _full(X, label), crease + tissue(rng, X.shape, 0.0001)

    return paint


# ------------------------------------------------------------------------------ flowers


def petal(label: int, colours: dict, shape: Shape):
    """One tepal or petal (amaryllis): coloured with a pale stripe and a green throat."""

    def paint(X, Y, px, rng):
        half = X.max()
        hw = shape(Y) * half * 0.96
        cov = coverage(hw - np.abs(X), px) * (Y > 0.002) * (Y < 0.998)
        n = value_noise(rng, X.shape, 3)
        rgb = mix(
            mix(colours["dark"], colours["base"], np.clip(2 * n, 0, 1)), colours["light"], np.clip(2 * n - 1, 0, 1)
        )
        stripe = line_mask(X, 0.02 + 0.04 * (1 - Y)) * _smooth((0.65 - Y) / 0.3)
        rgb = mix(rgb, colours["stripe"], 0.8 * stripe)
        rgb = mix(rgb, colours["throat"], _smooth((0.15 - Y) / 0.12))
        rel = np.abs(X) / np.maximum(hw, 1e-6)
        lines = line_mask(((X * 60) % 1.0) - 0.5, 0.15)
        rgb = rgb * (1 - 0.15 * lines * (1 - rel))[..., None]
        return cov, rgb, _full(X, label), groove(lines, 0.0008) + groove(stripe, 0.003)

    return paint


def radial_flower(
    label: int, colours: dict, petals: int, *, petal_width: float = 0.55, centre: float = 0.15, rays: bool = False
):
    """A flower seen face on: ``petals`` rounded petals (or thin rays) around a centre disc."""

    def paint(X, Y, px, rng):
        dx, dy = X, Y - 0.5
        r, th = np.hypot(dx, dy), np.arctan2(dx, dy)
        phase = rng.uniform(0, 2 * np.pi)
        k = (th + phase) * petals / (2 * np.pi)
        delta = np.abs(k - np.round(k)) * 2 * np.pi / petals  # angle to the nearest petal's axis
        R = 0.47 * (0.92 + 0.08 * value_noise(rng, X.shape, 3))
        if rays:
            f_p = np.minimum(0.006 + 0.01 * r / 0.47 - delta * r, R - r)
        else:
            w = petal_width * np.pi / petals
            prof = np.sqrt(np.clip(1 - (delta / w) ** 2, 0, 1))
            f_p = (centre * 0.47 + (R - centre * 0.47) * prof) - r
        f = np.maximum(f_p, centre * 0.47 - r)
        cov = coverage(f, px)
        n = value_noise(rng, X.shape, 4)
        rgb = mix(
            mix(colours["dark"], colours["base"], np.clip(2 * n, 0, 1)), colours["light"], np.clip(2 * n - 1, 0, 1)
        )
        rgb = mix(rgb, colours["inner"], _smooth((0.25 - r / 0.47) / 0.25) * 0.8)
        if "guides" in colours:
            g = line_mask(delta * r, 0.003) * _smooth((0.6 - r / 0.47) / 0.3)
            rgb = mix(rgb, colours["guides"], g * 0.8)
        rgb = mix(rgb, colours["disc"], _smooth((centre * 0.47 - r) / 0.01))
        return cov, rgb, _full(X, label)

    return paint


def sprig(leaf_label: int, stem_label: int, colours: dict, twig_colour: tuple, pairs: int):
    """A twig with ``pairs`` opposite pairs of small elliptic leaves (boxwood filler cards);
    texels along the twig are labelled ``stem_label``, the rest ``leaf_label``."""

    def paint(X, Y, px, rng):
        half = X.max()
        tw = 0.012 * (1.2 - 0.6 * Y)
        f_twig = np.minimum(tw - np.abs(X), 0.9 - Y)
        f_leaf = np.full(X.shape, -1.0)
        L, W = 0.9 * half, 0.28 * half
        for k in range(pairs):
            y0 = 0.12 + 0.75 * k / max(pairs - 1, 1) * 0.95
            for side in (-1.0, 1.0):
                ang = side * rng.uniform(0.7, 1.1)  # leaf axis from +Y
                lx, ly = X * np.cos(ang) - (Y - y0) * np.sin(ang), X * np.sin(ang) + (Y - y0) * np.cos(ang)
                # ellipse from the twig outward along the rotated x axis
                length = L * rng.uniform(0.8, 1.0)
                e = np.sqrt(((side * lx - length / 2) / (length / 2)) ** 2 + (ly / W) ** 2)
                f_leaf = np.maximum(f_leaf, (1 - e) * W)
        tipx, tipy = X, Y - 0.93
        e = np.sqrt((tipx / W) ** 2 + (tipy / 0.07) ** 2)
        f_leaf = np.maximum(f_leaf, (1 - e) * W)
        cov = coverage(np.maximum(f_twig, f_leaf), px)
        rgb = leaf_colour(X, Y, rng, colours["base"], colours["light"], colours["dark"], None, None, 3)
        rgb = np.where((f_twig > f_leaf)[..., None], np.asarray(twig_colour, float), rgb)
        lab = np.where((f_twig > f_leaf) & (np.abs(X) < 2 * tw), stem_label, leaf_label).astype(np.uint8)
        return cov, rgb, lab

    return paint


# ------------------------------------------------------------------------------- ageing


def tinted(painter, factor: np.ndarray):
    """``painter``'s leaf with its colour times ``factor`` (linear R, G, B): one leaf variant's
    own shade within its species."""

    def paint(X, Y, px, rng):
        cov, rgb, labels, *relief = painter(X, Y, px, rng)
        linear = srgb_to_linear(np.clip(rgb, 0.0, 1.0)) * np.asarray(factor)
        return (cov, linear_to_srgb(np.clip(linear, 0.0, 1.0)), labels, *relief)

    return paint


#: linear sRGB's luminance weights (Rec. 709)
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def aged(painter, yellowing: float, spots: int, dry_tip: float, yellow: np.ndarray, brown: np.ndarray):
    """``painter``'s leaf, aged: blotches yellowing up to ``yellowing`` (0..1) of the way, up
    to ``spots`` brown spots, a dried tip up to ``dry_tip`` of the length. ``yellow`` and
    ``brown`` are the linear colours of a yellowed and a dead leaf per unit of the healthy
    leaf's luminance (:func:`.optics.aged_colour`): an aged texel takes that colour at its own
    luminance, so the texture's light and shade stay and the hue is the optics' (a tint that
    multiplied would overshoot on parts painted yellow already, such as grass tips)."""

    def paint(X, Y, px, rng):
        cov, rgb, labels, *relief = painter(X, Y, px, rng)
        linear = srgb_to_linear(np.clip(rgb, 0.0, 1.0))
        lum = (linear @ LUMINANCE)[..., None]
        blotch = _smooth((value_noise(rng, X.shape, 3) - 0.35) / 0.4) * yellowing * rng.uniform(0.4, 1.0)
        linear = linear + blotch[..., None] * (lum * np.asarray(yellow) - linear)
        dead = np.zeros(X.shape)
        inside = cov > 0.5
        if spots > 0 and inside.any():
            ys, xs = np.nonzero(inside)
            for i in rng.integers(0, len(ys), int(rng.integers(0, spots + 1))):
                r = rng.uniform(0.006, 0.02)
                d = np.hypot(X - X[ys[i], xs[i]], Y - Y[ys[i], xs[i]]) / r
                dead = np.maximum(dead, _smooth((1.15 - d) / 0.3))
        if dry_tip > 0:
            edge = 1 - dry_tip * rng.uniform(0.4, 1.0) * (0.8 + 0.4 * value_noise(rng, X.shape, 6))
            dead = np.maximum(dead, _smooth((Y - edge) / 0.02))
        linear = linear + dead[..., None] * (lum * np.asarray(brown) - linear)
        rgb = linear_to_srgb(np.clip(linear, 0.0, 1.0))
        return (cov, rgb, labels, *relief)

    return paint
