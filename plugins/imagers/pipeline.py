"""The imager: what a colour camera's sensor and ISP make of the light a renderer computes.

A view's linear radiance (1 = a white Lambertian surface under irradiance 1, which the run's
``imager.lux`` says how bright that is) becomes, per pixel and in this order:

1. image-plane illuminance through the lens (``E = L lux / (4 N^2)`` at f-number N) falling off
   towards the corners by the lens's relative illumination (vignetting);
2. photo-electrons over the exposure time on an RGGB Bayer mosaic: each site sees its colour
   filter's share (the sensor's raw response, so that a grey is not grey in raw), Poisson
   distributed (shot noise) and clipped at the full-well capacity;
3. a digital number: the electrons times the analogue gain and the conversion gain (the ADC's
   range spans the full well at gain 1), plus Gaussian read noise, plus the black level,
   rounded and clipped to the bit depth: the raw frame;
4. the ISP: black level off, demosaicing (OpenCV), white balance, the colour matrix to linear
   sRGB, the sRGB transfer function to 8 bits, and optionally JPEG at a quality.

Auto-exposure meters the mean luminance of the developed image, as Raspberry Pi's libcamera
AGC does, and moves the total exposure (time, then gain) a fraction of the way to its target
each frame; the camera streams ``ae_frames`` frames between two shots, so each view's exposure
follows from the last. A fixed exposure skips it. Noise is drawn from a generator seeded by the
run's seed and the view: the same seed gives the same bytes.

Sensor figures are the manufacturers' where published; the rest are stated as assumed on each
preset (:data:`IMAGERS`). Each preset is an imager backend of its own name
(:mod:`agrisim.plugins.imagers`), built by :func:`preset`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from agrisim import interfaces
from agrisim.config import ImagerConfig
from agrisim.errors import UserError
from agrisim.interfaces import Exposure, Shot
from agrisim.options import Options
from agrisim.scene.colour import encode_srgb8

#: photons per second per m^2 in one lux of 555 nm light (1 lx = 1/683 W/m^2; h c / 555 nm =
#: 3.58e-19 J): the photometric scale the sensor's quantum efficiency is stated against
PHOTONS_PER_LUX_S_M2 = 4.09e15
#: Rec. 709 / sRGB luminance weights of linear R, G, B
LUMA = np.array([0.2126, 0.7152, 0.0722])


@dataclass(frozen=True)
class SensorFigures:
    """A colour image sensor and the processing after it (one of :data:`IMAGERS`)."""

    name: str
    sensor: str
    pixel_um: float
    """Pixel pitch, micrometres."""
    f_number: float
    """The lens's f-number (sets the image-plane illuminance)."""
    quantum_efficiency: float
    """Electrons per photon of the green channel, against photons at 555 nm (effective, with
    the colour filter and fill factor)."""
    full_well_e: float
    """Electrons a pixel holds before it saturates."""
    read_noise_e: float
    """Read noise, electrons RMS (input-referred, at gain 1)."""
    bit_depth: int
    black_level: int
    """Digital number of no light, at ``bit_depth``."""
    gain_range: tuple[float, float]
    """Analogue gain, least and most."""
    shutter_range_s: tuple[float, float]
    """Exposure time, shortest and longest, seconds."""
    raw_white: tuple[float, float]
    """(R/G, B/G) of a grey in raw under the lab's light: the colour filters' balance, which
    white balance undoes."""
    ccm: tuple[tuple[float, float, float], ...]
    """White-balanced raw RGB to linear sRGB (rows sum to 1: grey stays grey)."""
    shading: tuple[float, float]
    """(a, b) of the lens's relative illumination ``1 / (1 + a r^2 + b r^4)``, r the distance
    from the image centre over the half-diagonal."""
    ae_target: float
    """Mean luminance the auto-exposure aims for (0..1 of the raw range)."""
    ae_speed: float
    """Share of the way to its target the auto-exposure moves each frame."""
    ae_startup_frames: int
    """Frames at full speed before the first view (the camera starts streaming)."""
    sources: str
    """Where each figure comes from, and which are assumed."""

    @property
    def white_level(self) -> int:
        return (1 << self.bit_depth) - 1

    @property
    def conversion_gain(self) -> float:
        """Digital numbers per electron at gain 1: the ADC's range spans the full well."""
        return (self.white_level - self.black_level) / self.full_well_e

    def at_bit_depth(self, bits: int) -> SensorFigures:
        """This sensor read out at ``bits`` (the black level scaled with the range)."""
        black = round(self.black_level * 2.0 ** (bits - self.bit_depth))
        return replace(self, bit_depth=bits, black_level=black)

    def electrons_per_s(self, lux: float) -> float:
        """Photo-electrons per second in a green pixel at the image centre from a white
        Lambertian surface under ``lux`` (image-plane illuminance ``lux / (4 N^2)``)."""
        area = (self.pixel_um * 1e-6) ** 2
        return lux / (4.0 * self.f_number**2) * PHOTONS_PER_LUX_S_M2 * area * self.quantum_efficiency

    def raw_response(self) -> np.ndarray:
        """3 x 3: linear sRGB radiance to the sensor's raw R, G, B (the colour matrix undone,
        then the filters' balance), so that the ISP's white balance and matrix give it back."""
        return np.diag([self.raw_white[0], 1.0, self.raw_white[1]]) @ np.linalg.inv(np.asarray(self.ccm))

    def white_balance(self) -> np.ndarray:
        """The ISP's gains on raw R, G, B."""
        return np.array([1.0 / self.raw_white[0], 1.0, 1.0 / self.raw_white[1]])


# Raspberry Pi's own tuning of the Camera Module 3 Wide (libcamera, src/ipa/rpi/vc4/data/
# imx708_wide.json): black level 4096 of 16 bits, the AGC's y_target 0.16, speed 0.15 and 5
# start-up frames, the normal exposure profile's 100 us - 66.7 ms and gains 1-16, the colour
# matrix at 5901 K and the grey's raw R/G, B/G at 5715 K (ct_curve), and the shading fitted to
# its luminance table (rms 6%, corners at 25% of the centre).
_IMX708_CCM = (
    (1.64439, -0.48855, -0.15585),
    (-0.29149, 1.67122, -0.37972),
    (-0.03111, -0.44052, 1.47163),
)

IMAGERS: dict[str, SensorFigures] = {
    "imx708": SensorFigures(
        name="imx708",
        sensor="Sony IMX708 (Raspberry Pi Camera Module 3 Wide)",
        pixel_um=1.4,
        f_number=2.2,
        quantum_efficiency=0.5,
        full_well_e=6000.0,
        read_noise_e=2.0,
        bit_depth=10,
        black_level=64,
        gain_range=(1.0, 16.0),
        shutter_range_s=(100e-6, 66.666e-3),
        raw_white=(0.4668, 0.5898),
        ccm=_IMX708_CCM,
        shading=(3.903, -0.915),
        ae_target=0.16,
        ae_speed=0.15,
        ae_startup_frames=5,
        sources=(
            "published: 1.4 um pixels, f/2.2, 10-bit raw (Raspberry Pi Camera Module 3 product brief); "
            "black level, gains, shutter range, AE target and speed, colour matrix, grey balance and lens "
            "shading from libcamera's imx708_wide.json tuning; assumed: full well 6000 e-, read noise 2 e-, "
            "QE 0.5 (Sony publishes none)"
        ),
    ),
    "ov2740": SensorFigures(
        name="ov2740",
        sensor="OmniVision OV2740 (RealSense D4xx colour camera)",
        pixel_um=1.4,
        f_number=2.0,
        quantum_efficiency=0.5,
        full_well_e=4500.0,
        read_noise_e=2.5,
        bit_depth=10,
        black_level=64,
        gain_range=(1.0, 16.0),
        shutter_range_s=(100e-6, 33.333e-3),
        raw_white=(0.55, 0.62),
        ccm=_IMX708_CCM,
        shading=(1.287, 0.414),
        ae_target=0.16,
        ae_speed=0.15,
        ae_startup_frames=5,
        sources=(
            "published: 1.4 um pixels, 1920x1080, 10-bit raw (OmniVision OV2740 product brief), 30 fps "
            "(RealSense D400 datasheet); assumed: full well 4500 e-, read noise 2.5 e-, QE 0.5, black level 64, "
            "gains 1-16, the IMX708's colour matrix and AE, a grey's raw balance 0.55/0.62, and the cos^4 "
            "law of the D435 colour camera's 69 x 42 degree field as shading"
        ),
    ),
}


def relative_illumination(imager: SensorFigures, height: int, width: int) -> np.ndarray:
    """H x W float32: the lens's vignetting, 1 at the image centre."""
    a, b = imager.shading
    half = np.hypot(width, height) / 2.0
    y = (np.arange(height, dtype=np.float64) + 0.5 - height / 2.0) / half
    x = (np.arange(width, dtype=np.float64) + 0.5 - width / 2.0) / half
    r2 = y[:, None] ** 2 + x[None, :] ** 2
    return (1.0 / (1.0 + a * r2 + b * r2 * r2)).astype(np.float32)


def bayer_sites(height: int, width: int) -> np.ndarray:
    """H x W uint8: the colour of each pixel's filter in an RGGB mosaic (0 R, 1 G, 2 B)."""
    sites = np.ones((height, width), np.uint8)
    sites[0::2, 0::2] = 0
    sites[1::2, 1::2] = 2
    return sites


@dataclass
class ImagePipeline(interfaces.Imager):
    """A :class:`SensorFigures` in a run: its light level, exposure mode and the auto-exposure's
    state from shot to shot.

    ``exposure`` None is auto-exposure; otherwise (time s, gain) fixed. ``jpeg_quality`` 0
    keeps the developed image lossless, 1..100 passes it through JPEG as a streaming camera
    does."""

    imager: SensorFigures
    lux: float = 1000.0
    exposure: tuple[float, float] | None = None
    ae_frames: int = 15
    jpeg_quality: int = 0
    seed: int = 0
    _state: Exposure | None = field(default=None, init=False, repr=False)
    _shading: dict[tuple[int, int], np.ndarray] = field(default_factory=dict, init=False, repr=False)

    # -- light to electrons -------------------------------------------------------------------
    def _shade(self, h: int, w: int) -> np.ndarray:
        if (h, w) not in self._shading:
            self._shading[(h, w)] = relative_illumination(self.imager, h, w)
        return self._shading[(h, w)]

    def electrons(self, radiance: np.ndarray, time_s: float) -> np.ndarray:
        """H x W float32: the mean photo-electrons each site of the mosaic collects from
        ``radiance`` (H x W x 3 linear sRGB) in ``time_s`` (before noise and the full well)."""
        h, w = radiance.shape[:2]
        response = self.imager.raw_response().astype(np.float32)
        rad = np.asarray(radiance, np.float32)
        raw = np.empty((h, w), np.float32)
        # each site sees its own filter's channel only (RGGB)
        for (dy, dx), c in (((0, 0), 0), ((0, 1), 1), ((1, 0), 1), ((1, 1), 2)):
            raw[dy::2, dx::2] = rad[dy::2, dx::2] @ response[c]
        np.maximum(raw, 0.0, out=raw)
        return raw * self._shade(h, w) * np.float32(self.imager.electrons_per_s(self.lux) * time_s)

    def read_out(self, electrons: np.ndarray, gain: float, rng: np.random.Generator) -> np.ndarray:
        """The raw frame (H x W uint16 digital numbers): shot noise, the full well, gain, read
        noise, black level, rounding and the ADC's range."""
        im = self.imager
        collected = np.minimum(rng.poisson(electrons).astype(np.float32), np.float32(im.full_well_e))
        dn = collected * np.float32(im.conversion_gain * gain)
        dn += rng.normal(0.0, im.read_noise_e * im.conversion_gain * gain, dn.shape).astype(np.float32)
        dn += np.float32(im.black_level)
        return np.clip(np.rint(dn), 0, im.white_level).astype(np.uint16)

    # -- raw to RGB ---------------------------------------------------------------------------
    def develop_linear(self, raw: np.ndarray) -> np.ndarray:
        """H x W x 3 float32 linear sRGB, 1 = the raw range's top: demosaiced (OpenCV), white
        balanced, clipped where any channel saturates, and through the colour matrix."""
        import cv2

        im = self.imager
        span = float(im.white_level - im.black_level)
        # demosaic at 16 bits: black level off and scaled up, so that rounding costs nothing
        scale = 65535.0 / span
        lifted = np.clip((raw.astype(np.float32) - im.black_level) * np.float32(scale), 0, 65535)
        rgb = cv2.cvtColor(np.rint(lifted).astype(np.uint16), cv2.COLOR_BayerRGGB2RGB).astype(np.float32)
        gains = im.white_balance()
        rgb *= (gains / 65535.0).astype(np.float32)
        # a site clipped at the raw range's top says only "at least this bright": white balanced,
        # a clipped green beside unclipped gains on red and blue turns a blown highlight magenta.
        # ISPs clip every channel at the level where the weakest-gained one saturates, so that
        # blown highlights are white (dcraw's highlight mode 0 does the same)
        np.minimum(rgb, np.float32(gains.min()), out=rgb)
        return rgb @ np.asarray(im.ccm, np.float32).T

    def develop(self, raw: np.ndarray) -> np.ndarray:
        """The 8-bit sRGB image of a raw frame (JPEG-compressed when ``jpeg_quality`` > 0)."""
        linear = self.develop_linear(raw)
        h, w = linear.shape[:2]
        rgb = np.empty((h * w, 3), np.uint8)
        encode_srgb8(np.ascontiguousarray(linear.reshape(-1, 3)), rgb)
        rgb = rgb.reshape(h, w, 3)
        if self.jpeg_quality:
            import cv2

            ok, data = cv2.imencode(".jpg", rgb[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
            decoded = cv2.imdecode(data, cv2.IMREAD_COLOR) if ok else None
            assert decoded is not None, "OpenCV could not encode the view as JPEG"
            rgb = np.ascontiguousarray(decoded[..., ::-1])
        return rgb

    # -- exposure -----------------------------------------------------------------------------
    def metered(self, radiance: np.ndarray, total: float) -> float:
        """The mean luminance the ISP would develop from ``radiance`` at total exposure
        ``total`` (time x gain), noise-free, highlights clipped: what the AE reads."""
        return self._meter(self._luminance(radiance), total)

    def _luminance(self, radiance: np.ndarray) -> np.ndarray:
        """The shaded luminance of every 4th pixel each way: what the meter reads (a camera's
        AE statistics are a coarse grid too)."""
        h, w = radiance.shape[:2]
        y = np.asarray(radiance[::4, ::4], np.float32) @ LUMA.astype(np.float32)
        return y * self._shade(h, w)[::4, ::4]

    def _meter(self, luminance: np.ndarray, total: float) -> float:
        im = self.imager
        # the developed value of a grey: electrons over the full well, times the gain
        k = im.electrons_per_s(self.lux) * total / im.full_well_e
        return float(np.minimum(luminance * np.float32(k), 1.0).mean())

    def _split(self, total: float) -> Exposure:
        """Time first, then gain (the exposure profiles of libcamera): the longest time up to
        the sensor's limit, the rest as gain."""
        im = self.imager
        t = float(np.clip(total, im.shutter_range_s[0], im.shutter_range_s[1]))
        g = float(np.clip(total / t, im.gain_range[0], im.gain_range[1]))
        return Exposure(t, g)

    def auto_expose(self, radiance: np.ndarray) -> Exposure:
        """The exposure of the next shot of ``radiance``: the AE's state moved ``ae_frames``
        frames towards the target (``ae_startup_frames`` at full speed before the first)."""
        im = self.imager
        if self._state is None:
            total, frames = self._split(10e-3).total, [(1.0, im.ae_startup_frames)]
        else:
            total, frames = self._state.total, []
        frames.append((im.ae_speed, self.ae_frames))
        lo = im.shutter_range_s[0] * im.gain_range[0]
        hi = im.shutter_range_s[1] * im.gain_range[1]
        luminance = self._luminance(radiance)
        for speed, n in frames:
            for _ in range(n):
                y = self._meter(luminance, total)
                want = total * im.ae_target / max(y, 1e-6)
                total = float(np.clip(total + speed * (want - total), lo, hi))
        shot = self._split(total)
        return Exposure(shot.time_s, shot.gain, self._meter(luminance, shot.total))

    def at_exposure(self, exposure: Exposure) -> ImagePipeline:
        """This pipeline at a fixed ``exposure`` (a frame shot again as it was)."""
        return replace(self, exposure=(exposure.time_s, exposure.gain))

    def resume_from(self, exposure: Exposure) -> None:
        """Go on from a shot taken before (``--resume``): the next auto-exposure starts there."""
        self._state = exposure

    # -- one view -----------------------------------------------------------------------------
    def shoot(self, radiance: np.ndarray, view: int) -> Shot:
        """One view's shot of ``radiance`` (H x W x 3 linear), its noise seeded by the run's
        seed and ``view`` (the same pair gives the same bytes)."""
        if self.exposure is None:
            exposure = self.auto_expose(radiance)
        else:
            t, g = self.exposure
            exposure = Exposure(t, g, self.metered(radiance, t * g))
        self._state = exposure
        rng = np.random.default_rng([self.seed, view])
        raw = self.read_out(self.electrons(radiance, exposure.time_s), exposure.gain, rng)
        return Shot(self.develop(raw), raw, exposure)

    def describe(self) -> dict[str, Any]:
        """The imager's figures and settings, for the run's record."""
        im = self.imager
        return {
            "name": im.name,
            "sensor": im.sensor,
            "pixel_um": im.pixel_um,
            "f_number": im.f_number,
            "quantum_efficiency": im.quantum_efficiency,
            "full_well_e": im.full_well_e,
            "read_noise_e": im.read_noise_e,
            "bit_depth": im.bit_depth,
            "black_level": im.black_level,
            "conversion_gain_dn_per_e": im.conversion_gain,
            "bayer": "RGGB",
            "lux": self.lux,
            "exposure": "auto" if self.exposure is None else {"time_s": self.exposure[0], "gain": self.exposure[1]},
            "jpeg_quality": self.jpeg_quality,
            "sources": im.sources,
        }


def preset(figures: SensorFigures, settings: ImagerConfig, seed: int) -> ImagePipeline:
    """The image pipeline of ``figures`` that a run's ``[imager]`` settings describe, its noise
    seeded by the run's ``seed``; a fixed exposure outside the sensor's ranges is refused."""
    if settings.bit_depth is not None:
        figures = figures.at_bit_depth(settings.bit_depth)
    fixed = None if settings.exposure == "auto" else (float(settings.exposure), settings.gain)
    if fixed is not None:
        (t0, t1), (g0, g1) = figures.shutter_range_s, figures.gain_range
        if not t0 <= fixed[0] <= t1:
            raise UserError(f"imager {figures.name!r} exposes {t0 * 1e3:g}-{t1 * 1e3:g} ms, not {fixed[0] * 1e3:g} ms")
        if not g0 <= fixed[1] <= g1:
            raise UserError(f"imager {figures.name!r} has analogue gains {g0:g}-{g1:g}, not {fixed[1]:g}")
    return ImagePipeline(figures, settings.lux, fixed, settings.ae_frames, settings.jpeg_quality, seed=seed)


def imx708(settings: ImagerConfig, seed: int, options: Options) -> ImagePipeline:
    """The ``imx708`` imager backend's factory."""
    return preset(IMAGERS["imx708"], settings, seed)


def ov2740(settings: ImagerConfig, seed: int, options: Options) -> ImagePipeline:
    """The ``ov2740`` imager backend's factory."""
    return preset(IMAGERS["ov2740"], settings, seed)
