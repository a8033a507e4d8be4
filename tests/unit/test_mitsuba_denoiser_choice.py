"""Which denoiser the mitsuba renderer takes (``denoise`` and ``denoiser``): OIDN where pyoidn
is installed, OptiX with the CUDA variant, none with a warning where neither can run, and a
clear refusal where the one asked for cannot. No rendering: the choice alone (OptiX's images are
checked on the GPU machine, tests/gpu/test_mitsuba_cuda.py)."""

from __future__ import annotations

import logging

import pytest

from agrisim.errors import ConfigError
from agrisim.plugins.render.mitsuba import denoise
from agrisim.plugins.render.mitsuba.options import MitsubaOptions

CPU, GPU = "llvm_ad_rgb", "cuda_ad_rgb"


@pytest.fixture
def no_pyoidn(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(denoise, "_pyoidn", lambda: None)


def test_auto_takes_oidn_where_pyoidn_is_installed() -> None:
    pytest.importorskip("pyoidn")
    assert denoise.chosen(MitsubaOptions(), CPU) == "oidn"
    assert denoise.chosen(MitsubaOptions(), GPU) == "oidn"


def test_auto_takes_optix_on_the_gpu_without_pyoidn(no_pyoidn: None) -> None:
    assert denoise.chosen(MitsubaOptions(), GPU) == "optix"


def test_auto_renders_undenoised_with_a_warning_where_none_can_run(
    no_pyoidn: None, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING):
        assert denoise.chosen(MitsubaOptions(), CPU) is None
    assert "without one" in caplog.text


def test_enough_samples_or_off_need_none() -> None:
    assert denoise.chosen(MitsubaOptions(spp=denoise.AUTO_BELOW_SPP), GPU) is None
    assert denoise.chosen(MitsubaOptions(denoise="off", denoiser="optix"), CPU) is None


@pytest.mark.parametrize(
    ("options", "pyoidn", "words"),
    [
        ({"denoiser": "optix"}, True, ["denoiser = 'optix'", "CUDA variant"]),
        ({"denoiser": "optix", "denoise": "on"}, True, ["denoiser = 'optix'", "CUDA variant"]),
        ({"denoise": "on"}, False, ["denoise = 'on'", "pyoidn", "OptiX"]),
        ({"denoiser": "oidn"}, False, ["denoiser = 'oidn'", "pyoidn"]),
    ],
)
def test_a_denoiser_that_cannot_run_here_is_refused(
    monkeypatch: pytest.MonkeyPatch, options: dict, pyoidn: bool, words: list[str]
) -> None:
    if not pyoidn:
        monkeypatch.setattr(denoise, "_pyoidn", lambda: None)
    elif denoise._pyoidn() is None:
        pytest.skip("pyoidn is not installed")
    with pytest.raises(ConfigError) as info:
        denoise.chosen(MitsubaOptions(**options), CPU)
    for word in words:
        assert word in str(info.value)
