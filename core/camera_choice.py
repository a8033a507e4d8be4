"""The run's camera from its settings: a calibration file, or a preset at a resolution."""

from __future__ import annotations

from typing import Any

from agrisim.scene.calibration import read_calibration
from agrisim.scene.camera import CameraModel, preset


def camera_of(settings: Any) -> CameraModel:
    """The camera of ``settings`` (:class:`agrisim.config.CameraConfig`): the calibration file
    when one is given, else the preset at the resolution."""
    if settings.calibration is not None:
        return read_calibration(settings.calibration)
    return preset(settings.preset, settings.resolution)
