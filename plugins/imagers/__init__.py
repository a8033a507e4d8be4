"""Imagers: what a colour camera's sensor and image processing make of each view's light
(``[imager] model``, ``--imager``). ``imx708`` (Raspberry Pi Camera Module 3) and ``ov2740``
(RealSense D4xx colour) share one model of a Bayer sensor and its ISP (:mod:`.pipeline`), each
with its own figures; ``none`` (no imager) keeps the renderer's noise-free images."""

from __future__ import annotations

from agrisim import BackendSpec, hookimpl
from agrisim.kinds import lazy

#: what the two presets share, for ``agrisim plugins``
_MODEL = "RGGB Bayer mosaic: vignetting, shot and read noise, full well, 10-bit ADC; auto-exposure; ISP"
_LIMITS = "no rolling shutter, motion blur, lens flare or fixed-pattern noise; one illuminant"


@hookimpl
def agrisim_imagers() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="imx708",
            factory=lazy("agrisim.plugins.imagers.pipeline:imx708"),
            description=f"Sony IMX708 (Raspberry Pi Camera Module 3 Wide), libcamera's tuning: {_MODEL}",
            limits=_LIMITS,
        ),
        BackendSpec(
            name="ov2740",
            factory=lazy("agrisim.plugins.imagers.pipeline:ov2740"),
            description=f"OmniVision OV2740 (RealSense D4xx colour camera): {_MODEL}",
            limits=_LIMITS,
        ),
    ]
