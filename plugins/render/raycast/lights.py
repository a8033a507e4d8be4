"""The scene's lights as arrays, for direct lighting (Lambert, sampled shadows: :mod:`.shading`).

Units are renderer-relative: a light of ``intensity`` I at distance r lights a surface facing it
with irradiance ``I / r^2``, times its colour and

* ``area``: the cosine between its ``direction`` and the way to the point (a Lambertian disc of
  ``radius`` facing ``direction``; shadow rays aim at uniform points on the disc);
* ``spot``: its cone, full inside 90% of ``cone_deg`` and fading smoothly to 0 at the edge;
* ``point``: 1 in every direction.

Shadows: ``samples`` rays per point are shared among the lights, each picking a light with
probability proportional to its unshadowed contribution there (stratified, so every light gets its
share of the rays, and a point no shadow reaches carries no noise), then one of 1024 points
spread evenly over that light's disc. Optionally adaptive: after a few samples, only points whose
samples disagree (penumbrae) get the rest.
"""

from __future__ import annotations

import numpy as np

from agrisim.scene.model import Light

F32 = np.float32
#: shadow rays stop this fraction of their length short of the light (a lamp's own housing
#: must not shadow it): ``occluded`` tests the segment up to ``SHADOW_TFAR`` of its length
SHADOW_TFAR = 1.0 - 1e-3
#: points per area light that shadow rays aim at
DISC_POINTS = 1024


class LightTable:
    """The scene's lights as arrays (:mod:`.shading` lights surfaces with them)."""

    def __init__(self, lights: list[Light]) -> None:
        self.n = len(lights)
        self.kind = [light.kind for light in lights]
        self.position = np.array([np.asarray(li.position, np.float64) for li in lights], F32).reshape(-1, 3)
        d = np.array([np.asarray(li.direction, np.float64) for li in lights]).reshape(-1, 3)
        norm = np.linalg.norm(d, axis=1, keepdims=True)
        d = d / np.where(norm > 0, norm, 1.0)
        self.direction = d.astype(F32)
        self.color = np.array([li.color for li in lights], F32).reshape(-1, 3)
        self.luminance = self.color.mean(axis=1)
        #: colour per unit of the scalar weight (which uses the mean of the colour)
        self.tint = (self.color / np.maximum(self.luminance, 1e-12)[:, None]).astype(F32)
        #: all lights the same colour: irradiance is a scalar times that colour
        self.uniform = bool(self.n == 0 or np.allclose(self.tint, self.tint[0]))
        self.power = np.array([li.intensity for li in lights], F32) * self.luminance
        self.radius = np.array([li.radius if li.kind == "area" else 0.0 for li in lights], F32)
        cone = np.radians([min(max(li.cone_deg, 0.0), 180.0) for li in lights])
        self.cos_outer = np.cos(cone).astype(F32)
        self.cos_inner = np.cos(0.9 * cone).astype(F32)
        # width of each spot's fade, from full to nothing (never 0: it divides)
        self.width = np.array([max(self.cos_inner[i] - self.cos_outer[i], 1e-6) for i in range(self.n)], F32)
        # An orthonormal basis of each disc, for points on area lights.
        e1 = np.cross(d, np.array([0.0, 0.0, 1.0]))
        small = np.linalg.norm(e1, axis=1) < 1e-6
        e1[small] = np.cross(d[small], np.array([1.0, 0.0, 0.0]))
        e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-12)
        e2 = np.cross(d, e1)
        # Points where shadow rays aim: DISC_POINTS per light, uniform on area discs (a golden-
        # angle spiral: stratified, no clumps), all at the position for spot and point lights.
        k = np.arange(DISC_POINTS) + 0.5
        r = np.sqrt(k / DISC_POINTS)[:, None]
        phi = (k * np.pi * (3.0 - np.sqrt(5.0)))[:, None]
        pts = [
            np.asarray(li.position, np.float64) + self.radius[i] * r * (np.cos(phi) * e1[i] + np.sin(phi) * e2[i])
            for i, li in enumerate(lights)
        ]
        self.targets = (np.concatenate(pts) if pts else np.zeros((0, 3))).astype(F32)
