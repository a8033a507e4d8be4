"""The ``mono8`` imager: a monochrome global-shutter camera at a fixed exposure. Each pixel's
luminance (Rec. 709 weights of the linear radiance) is scaled by the light and the exposure,
gamma-encoded to 8 bits with Gaussian read noise (one grey level RMS, seeded by the run's seed
and the view) and given as R = G = B; the raw frame is the same grey levels, uint16."""

from __future__ import annotations

from typing import Any

import numpy as np

from agrisim import BackendSpec, hookimpl
from agrisim.interfaces import Exposure, Imager, Shot

LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)
#: the exposure it shoots at unless told another (a frame shot again as it was)
EXPOSURE = Exposure(0.004, 1.0)


class MonoImager(Imager):
    def __init__(self, lux: float, seed: int, exposure: Exposure = EXPOSURE) -> None:
        self.lux = lux
        self.seed = seed
        self.exposure = exposure

    def shoot(self, radiance: np.ndarray, view: int) -> Shot:
        luma = np.asarray(radiance, np.float32) @ LUMA
        # 1000 lx and 4 ms put a white surface at the top of the range
        signal = np.clip(luma * np.float32(self.lux / 1000.0 * self.exposure.total / EXPOSURE.total), 0.0, 1.0)
        noise = np.random.default_rng([self.seed, view]).normal(0.0, 1.0, luma.shape)
        grey = np.clip(np.rint(255.0 * signal ** (1 / 2.2) + noise), 0, 255).astype(np.uint8)
        shot = Exposure(self.exposure.time_s, self.exposure.gain, float(signal.mean()))
        return Shot(np.repeat(grey[..., None], 3, axis=2), grey.astype(np.uint16), shot)

    def resume_from(self, exposure: Exposure) -> None:
        pass  # a fixed exposure: nothing carries over from shot to shot

    def at_exposure(self, exposure: Exposure) -> MonoImager:
        return MonoImager(self.lux, self.seed, exposure)

    def describe(self) -> dict[str, Any]:
        return {
            "name": "mono8",
            "sensor": "monochrome global shutter (agrisim-mono-imager)",
            "lux": self.lux,
            "exposure": {"time_s": self.exposure.time_s, "gain": self.exposure.gain},
        }


def mono8(settings: Any, seed: int, options: Any) -> MonoImager:
    return MonoImager(settings.lux, seed)


@hookimpl
def agrisim_imagers() -> list[BackendSpec]:
    return [BackendSpec(name="mono8", factory=mono8, description="monochrome global-shutter camera, 8-bit grey")]
