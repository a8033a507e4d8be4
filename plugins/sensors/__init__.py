"""Depth sensors: what a depth camera beside the colour camera measures (``[sensor] backend``,
``--depth-sensor``). ``exact`` is the renderer's depth; ``azure-kinect-nfov`` the Azure
Kinect's time-of-flight camera simulated from its physics (:mod:`.tof`). A sensor's depth goes
to ``depth_sensor/`` on the colour camera's pixels (:mod:`.align`) and, by default, to the
reconstruction (``recon.depth``)."""

from __future__ import annotations

from agrisim import BackendSpec, hookimpl
from agrisim.capabilities import SensorCapabilities
from agrisim.kinds import lazy
from agrisim.plugins.sensors.tof import AzureKinectOptions


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
            capabilities=SensorCapabilities(points=False),
        ),
    ]
