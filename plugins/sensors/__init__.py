"""Depth sensors: what a depth camera beside the colour camera measures (``[sensor] backend``,
``--depth-sensor``). ``exact`` is the renderer's depth; ``azure-kinect-nfov`` the Azure
Kinect's time-of-flight camera simulated from its physics (:mod:`.tof`). A sensor's depth goes
to ``depth_sensor/`` on the colour camera's pixels (:mod:`.align`) and, by default, to the
reconstruction (``recon.depth``)."""

from __future__ import annotations

from typing import Any

from agrisim import BackendSpec, hookimpl
from agrisim.capabilities import SensorCapabilities
from agrisim.kinds import lazy
from agrisim.plugins.sensors import tof
from agrisim.plugins.sensors.stereo import DEVICES, StereoOptions, depth_range
from agrisim.plugins.sensors.tof import AzureKinectOptions


def _stereo(device: str) -> BackendSpec:
    d = DEVICES[device]

    def factory(scene: Any, cell: Any, settings: Any, options: StereoOptions) -> Any:
        from agrisim.plugins.sensors.stereo import StereoSensor

        return StereoSensor(scene, cell, settings, options, device)

    return BackendSpec(
        name=device,
        factory=factory,
        description=f"RealSense {device.upper()} stereo: infrared pair rendered ({d.baseline_m * 1000:g} mm baseline, "
        f"{d.hfov_deg:g}x{d.vfov_deg:g} deg, {'dot projector' if d.projector else 'no projector: texture only'}), "
        "OpenCV semi-global matching, left-right check, aligned to colour",
        options_model=StereoOptions,
        preflight=lambda config, options: depth_range(d, options) and None,
        limits="no lens distortion, rolling shutter or ASIC post-filters; an assumed dot pattern (60,000 dots); "
        "meshes only (not point plants)",
        capabilities=SensorCapabilities(points=False, range_m=(d.min_z_m, d.max_z_m)),
    )


@hookimpl
def agrisim_sensors() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="exact",
            factory=lazy("agrisim.plugins.sensors.exact:ExactSensor"),
            description="The renderer's exact depth (every pixel on the true surface); writes no depth_sensor/",
            capabilities=SensorCapabilities(points=True),
        ),
        BackendSpec(
            name="azure-kinect-nfov",
            factory=lazy("agrisim.plugins.sensors.tof:AzureKinectSensor"),
            description="Azure Kinect time of flight, NFOV unbinned (640x576, 75x65 deg): mixed pixels at edges, "
            "shot noise to the published 17 mm, low-signal and flying-pixel invalidation, aligned to colour",
            options_model=AzureKinectOptions,
            limits="no multipath, ambient light, illumination mask or temporal effects; one modulation frequency "
            "mixes, unwrapping is assumed right; meshes only (not point plants)",
            capabilities=SensorCapabilities(points=False, range_m=tof.RANGE_M),
        ),
        *(_stereo(device) for device in sorted(DEVICES)),
    ]
