"""Leaf optics from leaf biochemistry: PROSPECT-D (the ``prosail`` package) gives a leaf's
hemispherical reflectance and transmittance spectra from its structure and pigments; the CIE 1931
observer under D65 (``colour-science``) turns them into linear sRGB.

The species use it three times: a leaf's translucency (its transmitted colour per unit of
reflected colour, :attr:`agrisim.scene.model.Material.transmittance`) comes from its own
parameters; ageing (yellowing, brown spots, dry tips) gives an aged texel the aged leaf's colour
(less chlorophyll, brown pigments, less water) at the texel's own luminance (:func:`aged_colour`);
and every leaf holds its own amount of chlorophyll, its colour against the species' palest leaf
(:func:`chlorophyll_tints`) becoming its vertex colour.

Both libraries take seconds to import, so results are kept in agrisim's cache
(:mod:`agrisim.util.cache`), keyed by the parameters and the libraries' versions: only the first
plant ever built on a machine pays for them.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import threading
from dataclasses import dataclass
from importlib import metadata

import numpy as np

from agrisim.util.cache import cache_dir, write_cached

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Leaf:
    """PROSPECT-D's parameters of a leaf (Féret et al. 2017)."""

    n: float = 1.5
    """Structure: the number of layers of the leaf's mesophyll (1 thin .. 3 thick)."""
    cab: float = 40.0
    """Chlorophyll a + b, µg/cm²."""
    car: float = 8.0
    """Carotenoids, µg/cm²."""
    ant: float = 0.0
    """Anthocyanins, µg/cm²."""
    brown: float = 0.0
    """Brown pigments of senescence (arbitrary units, 0 .. ~2)."""
    cw: float = 0.012
    """Equivalent water thickness, cm."""
    cm: float = 0.005
    """Dry matter per area, g/cm²."""

    def aged(self, green: float = 0.25, brown: float = 0.4, water: float = 1.0) -> Leaf:
        """The same leaf ageing: ``green`` of its chlorophyll (carotenoids kept: yellowing),
        ``brown`` pigments, ``water`` of its water (less: drying)."""
        return dataclasses.replace(self, cab=self.cab * green, brown=self.brown + brown, cw=self.cw * water)


_memory: dict[str, tuple[RGB, RGB]] = {}
_lock = threading.Lock()


@functools.cache
def _versions() -> tuple[str, ...]:
    return tuple(metadata.version(p) for p in ("prosail", "colour-science"))


def _key(leaf: Leaf) -> str:
    return json.dumps([dataclasses.astuple(leaf), _versions()])


def leaf_rgb(leaf: Leaf) -> tuple[RGB, RGB]:
    """(reflectance, transmittance) of ``leaf`` in linear sRGB (1 = a white reflector under D65)."""
    key = _key(leaf)
    with _lock:
        if key in _memory:
            return _memory[key]
        path = cache_dir("leaf-optics") / "prospect-d.json"
        try:
            stored = json.loads(path.read_text())
        except (OSError, ValueError):
            stored = {}
        if key not in stored:
            stored[key] = _compute(leaf)
            write_cached(path, json.dumps(stored).encode())
        r, t = stored[key]
        _memory[key] = (tuple(r), tuple(t))  # type: ignore[assignment]
        return _memory[key]


#: the near-infrared wavelength depth cameras illuminate at (Azure Kinect, RealSense), nm
NIR_NM = 850


def leaf_nir(leaf: Leaf) -> float:
    """The leaf's hemispherical reflectance at :data:`NIR_NM` (what an active depth camera's
    light sees: :attr:`agrisim.scene.model.Material.nir`), from PROSPECT-D."""
    key = _key(leaf)
    with _lock:
        path = cache_dir("leaf-optics") / "prospect-d-nir.json"
        try:
            stored = json.loads(path.read_text())
        except (OSError, ValueError):
            stored = {}
        if key not in stored:
            import prosail

            wavelengths, refl, _ = prosail.run_prospect(
                leaf.n, leaf.cab, leaf.car, leaf.brown, leaf.cw, leaf.cm, ant=leaf.ant, prospect_version="D"
            )
            stored[key] = float(np.interp(NIR_NM, wavelengths, refl))
            write_cached(path, json.dumps(stored).encode())
        return float(stored[key])


def _compute(leaf: Leaf) -> tuple[list[float], list[float]]:
    import prosail

    wavelengths, refl, trans = prosail.run_prospect(
        leaf.n, leaf.cab, leaf.car, leaf.brown, leaf.cw, leaf.cm, ant=leaf.ant, prospect_version="D"
    )
    return spectrum_rgb(wavelengths, refl), spectrum_rgb(wavelengths, trans)


def spectrum_rgb(wavelengths: np.ndarray, values: np.ndarray) -> list[float]:
    """Linear sRGB of a reflectance (or transmittance) spectrum sampled every nanometre from at
    most 400 nm: the CIE 1931 2° observer under D65, so that 1 everywhere is (1, 1, 1);
    negative channels (a colour outside sRGB's gamut) are clipped to 0."""
    import colour

    visible = (wavelengths >= 360) & (wavelengths <= 780)
    shape = colour.SpectralShape(float(wavelengths[visible][0]), float(wavelengths[visible][-1]), 1.0)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
    sd = colour.SpectralDistribution(np.asarray(values, float)[visible], np.asarray(wavelengths, float)[visible])
    xyz = colour.sd_to_XYZ(sd, cmfs, d65) / 100.0
    rgb = colour.XYZ_to_RGB(xyz, "sRGB", apply_cctf_encoding=False)
    return [float(max(c, 0.0)) for c in rgb]


def translucency(leaf: Leaf) -> RGB:
    """The leaf's transmitted colour per unit of reflected colour, per linear sRGB channel."""
    r, t = leaf_rgb(leaf)
    return tuple(float(tc / max(rc, 1e-6)) for rc, tc in zip(r, t, strict=True))  # type: ignore[return-value]


def aged_colour(leaf: Leaf, aged: Leaf) -> np.ndarray:
    """The linear colour of ``aged`` per unit of the luminance of ``leaf`` (Rec. 709)."""
    r, _ = leaf_rgb(leaf)
    a, _ = leaf_rgb(aged)
    return np.asarray(a) / max(float(np.dot(r, [0.2126, 0.7152, 0.0722])), 1e-6)


def chlorophyll_tints(leaf: Leaf, factors: np.ndarray) -> np.ndarray:
    """(len(factors), 3): the reflectance of ``leaf`` with its chlorophyll times each factor,
    per linear sRGB channel of its own. Chlorophyll only absorbs, so factors of 1 or more give
    tints within 0..1: darker, and bluer where red is absorbed most."""
    r0 = np.maximum(np.asarray(leaf_rgb(leaf)[0]), 1e-6)
    rows = [np.asarray(leaf_rgb(dataclasses.replace(leaf, cab=leaf.cab * float(f)))[0]) / r0 for f in factors]
    return np.clip(np.asarray(rows), 0.0, 1.0)
