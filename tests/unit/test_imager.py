"""The imager against the models it claims: the photon transfer curve of EMVA 1288 (variance
against mean of flat fields) gives back the configured conversion gain, read noise and full
well; colours come back through the mosaic, white balance and colour matrix; the vignetting is
the preset's; the auto-exposure converges as its filter says; the same seed gives the same
bytes."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from agrisim.plugins.imagers.pipeline import IMAGERS, ImagePipeline, bayer_sites, relative_illumination


def _flat(imager_name: str, **changes: object) -> ImagePipeline:
    """A pipeline of the preset without its lens's shading (EMVA 1288 measures the bare sensor
    under a flat field)."""
    imager = dataclasses.replace(IMAGERS[imager_name], shading=(0.0, 0.0), **changes)
    return ImagePipeline(imager)


def _photon_transfer(pipe: ImagePipeline, gain: float, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean above black, temporal variance) in DN of the green sites of a flat grey card, one
    pair of frames per exposure time: half the variance of their difference, which no spatial
    pattern enters (EMVA 1288's method)."""
    grey = np.full((256, 256, 3), 0.5, np.float32)
    green = bayer_sites(256, 256) == 1
    means, variances = [], []
    for i, t in enumerate(times):
        electrons = pipe.electrons(grey, float(t))
        a, b = (
            pipe.read_out(electrons, gain, np.random.default_rng([7, i, k])).astype(np.float64)[green] for k in (0, 1)
        )
        means.append(0.5 * (a.mean() + b.mean()) - pipe.imager.black_level)
        variances.append(0.5 * np.var(a - b))
    return np.array(means), np.array(variances)


@pytest.mark.parametrize("name", sorted(IMAGERS))
@pytest.mark.parametrize("gain", [1.0, 8.0])
def test_the_photon_transfer_curve_gives_the_configured_gain_and_read_noise(name: str, gain: float) -> None:
    pipe = _flat(name)
    im = pipe.imager
    # from a few electrons to well past saturation
    k = im.conversion_gain * gain  # DN per electron
    saturation = min(im.full_well_e * k, im.white_level - im.black_level)  # DN above black
    full_t = saturation / k / (im.electrons_per_s(pipe.lux) * 0.5)  # the grey card's time to saturate
    times = np.concatenate([[0.0], np.geomspace(full_t * 2e-3, full_t * 3.0, 24)])  # a dark pair first
    mean, var = _photon_transfer(pipe, gain, times)
    dark_mean, dark_var = mean[0], var[0]
    # the dark frames' variance: read noise and rounding (1/12 DN^2; EMVA 1288's model of the
    # rounding holds where the read noise spans a digital number or more: at gain 8, not 1)
    read_dn2 = (im.read_noise_e * k) ** 2 + 1 / 12
    if im.read_noise_e * k > 1.0:
        assert dark_var == pytest.approx(read_dn2, rel=0.1)
    else:
        assert dark_var < read_dn2 + 0.1
    # shot noise: the variance grows as K x the mean (the slope is the system gain, DN/e-)
    linear = (mean < 0.7 * saturation) & (times > 0)
    slope = np.polyfit(mean[linear] - dark_mean, var[linear] - dark_var, 1)[0]
    assert slope == pytest.approx(k, rel=0.05)
    # saturated: the mean pins at the full well (or the ADC's top), the variance collapses
    assert mean[-1] == pytest.approx(saturation, rel=0.01)
    assert var[-1] < 0.05 * var[linear].max()


def test_the_read_noise_is_measured_in_the_dark() -> None:
    """No light: the raw frame's spread is the read noise (and the rounding), about the black
    level."""
    pipe = _flat("imx708")
    im = pipe.imager
    raw = pipe.read_out(np.zeros((256, 256), np.float32), 16.0, np.random.default_rng(3)).astype(np.float64)
    k = im.conversion_gain * 16.0
    assert raw.mean() == pytest.approx(im.black_level, abs=0.1)
    assert raw.std() == pytest.approx(np.hypot(im.read_noise_e * k, np.sqrt(1 / 12)), rel=0.05)


@pytest.mark.parametrize("name", sorted(IMAGERS))
def test_colours_come_back_through_the_mosaic_white_balance_and_matrix(name: str) -> None:
    """Flat patches of colour: the developed linear RGB (demosaiced by OpenCV, white balanced,
    through the colour matrix) is the radiance times the exposure, in expectation."""
    pipe = _flat(name)
    im = pipe.imager
    colours = np.array([[0.5, 0.5, 0.5], [0.6, 0.1, 0.05], [0.1, 0.5, 0.1], [0.05, 0.15, 0.6], [0.4, 0.35, 0.1]])
    radiance = np.repeat(colours[:, None, None, :], 64, axis=1).repeat(64, axis=2).reshape(-1, 64, 3)
    radiance = np.ascontiguousarray(radiance.astype(np.float32))
    # bright (the shot noise averages out over a patch), well below saturation in every channel
    t = 0.5 * im.full_well_e / (im.electrons_per_s(pipe.lux) * colours.max() * 1.6)
    developed = pipe.develop_linear(pipe.read_out(pipe.electrons(radiance, t), 1.0, np.random.default_rng(0)))
    scale = im.electrons_per_s(pipe.lux) * t / im.full_well_e
    for i, colour in enumerate(colours):
        patch = developed[i * 64 + 8 : i * 64 + 56, 8:56].reshape(-1, 3).mean(0)
        np.testing.assert_allclose(patch, colour * scale, rtol=0.03, atol=2e-3)


@pytest.mark.parametrize("name", sorted(IMAGERS))
def test_a_blown_highlight_is_white(name: str) -> None:
    """A lamp far past the full well in every channel develops to white, not to the magenta that
    white balancing a clipped green beside unclipped red and blue gains would give."""
    pipe = _flat(name)
    im = pipe.imager
    lamp = np.full((64, 64, 3), 50.0, np.float32)
    t = im.full_well_e / im.electrons_per_s(pipe.lux)  # the lamp holds 50 full wells
    rgb = pipe.develop(pipe.read_out(pipe.electrons(lamp, t), 1.0, np.random.default_rng(0)))
    assert rgb[8:56, 8:56].min() >= 250, rgb[8:56, 8:56].reshape(-1, 3).min(0)


def test_the_raw_frame_is_rggb() -> None:
    """A red surface lights the red sites (even rows, even columns) most, a blue one the blue
    sites (odd, odd): the mosaic is the RGGB that OpenCV's COLOR_BayerRGGB2RGB reads."""
    pipe = _flat("imx708")
    for colour, site in (((1.0, 0.0, 0.0), (0, 0)), ((0.0, 0.0, 1.0), (1, 1))):
        radiance = np.broadcast_to(np.array(colour, np.float32), (8, 8, 3))
        e = pipe.electrons(np.ascontiguousarray(radiance), 1e-3)
        quads = {(dy, dx): e[dy::2, dx::2].mean() for dy in (0, 1) for dx in (0, 1)}
        assert max(quads, key=quads.__getitem__) == site
    red = np.zeros((8, 8), np.uint16)
    red[0::2, 0::2] = 1000
    assert int(np.argmax(cv2.cvtColor(red, cv2.COLOR_BayerRGGB2RGB)[4, 4])) == 0


def test_vignetting_is_the_lens_shading() -> None:
    """A white wall through the wide lens: the corners get the preset's relative illumination
    (libcamera's IMX708 wide tuning: a quarter of the centre), in the developed image too."""
    pipe = ImagePipeline(IMAGERS["imx708"])
    h, w = 180, 320
    shading = relative_illumination(pipe.imager, h, w)
    a, b = pipe.imager.shading
    assert shading[0, 0] == pytest.approx(1 / (1 + a + b), rel=0.02)
    assert shading.max() == pytest.approx(1.0, abs=1e-3)
    white = np.ones((h, w, 3), np.float32)
    t = 0.3 * pipe.imager.full_well_e / pipe.imager.electrons_per_s(pipe.lux)
    developed = pipe.develop_linear(pipe.read_out(pipe.electrons(white, t), 1.0, np.random.default_rng(1)))
    y = developed @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    centre, corner = y[80:100, 150:170].mean(), y[2:12, 2:12].mean()
    assert corner / centre == pytest.approx(shading[2:12, 2:12].mean() / shading[80:100, 150:170].mean(), rel=0.05)


def test_the_auto_exposure_converges_as_its_filter_says() -> None:
    """From the start-up frames the first shot meets the target; a scene 3 times brighter is
    then approached by the share ``ae_speed`` each frame: after n frames (1 - speed)^n of the
    gap is left (the meter is linear while nothing clips)."""
    grey = np.full((90, 160, 3), 0.1, np.float32)
    pipe = ImagePipeline(IMAGERS["imx708"], ae_frames=4)
    first = pipe.shoot(grey, 0).exposure
    assert first.metered == pytest.approx(pipe.imager.ae_target, rel=1e-3)
    second = pipe.shoot(3 * grey, 1).exposure
    want = first.total / 3
    speed = pipe.imager.ae_speed
    assert (second.total - want) / (first.total - want) == pytest.approx((1 - speed) ** 4, rel=1e-4)
    # darker than the longest exposure reaches: the gain makes up the rest
    dark = ImagePipeline(IMAGERS["imx708"]).shoot(grey / 10, 0).exposure
    assert dark.time_s == pytest.approx(pipe.imager.shutter_range_s[1])
    assert dark.gain > 1.0 and dark.metered == pytest.approx(pipe.imager.ae_target, rel=0.01)


def test_a_fixed_exposure_is_kept() -> None:
    grey = np.full((32, 32, 3), 0.2, np.float32)
    shots = [ImagePipeline(IMAGERS["ov2740"], exposure=(0.004, 2.0)).shoot(g, 0).exposure for g in (grey, 4 * grey)]
    assert all((s.time_s, s.gain) == (0.004, 2.0) for s in shots)
    assert shots[1].metered == pytest.approx(4 * shots[0].metered, rel=1e-4)


def test_the_same_seed_gives_the_same_bytes() -> None:
    radiance = np.random.default_rng(5).random((60, 80, 3), dtype=np.float32)
    shots = [ImagePipeline(IMAGERS["imx708"], seed=s).shoot(radiance, v) for s, v in ((1, 2), (1, 2), (1, 3), (2, 2))]
    assert np.array_equal(shots[0].raw, shots[1].raw) and np.array_equal(shots[0].rgb, shots[1].rgb)
    assert not np.array_equal(shots[0].raw, shots[2].raw)  # another view
    assert not np.array_equal(shots[0].raw, shots[3].raw)  # another seed


def test_jpeg_costs_detail_by_its_quality() -> None:
    """The developed image through JPEG: the lower the quality, the further from the lossless
    image (OpenCV's codec, as a streaming camera's)."""
    radiance = np.random.default_rng(6).random((64, 64, 3), dtype=np.float32) * 0.3
    lossless = ImagePipeline(IMAGERS["imx708"]).shoot(radiance, 0).rgb.astype(np.float64)
    errors = [
        np.abs(ImagePipeline(IMAGERS["imx708"], jpeg_quality=q).shoot(radiance, 0).rgb - lossless).mean()
        for q in (95, 30)
    ]
    assert 0 < errors[0] < errors[1]


def test_a_lower_bit_depth_scales_the_black_level() -> None:
    im = IMAGERS["imx708"].at_bit_depth(12)
    assert (im.white_level, im.black_level) == (4095, 256)
    assert im.conversion_gain == pytest.approx(4 * IMAGERS["imx708"].conversion_gain, rel=0.01)
