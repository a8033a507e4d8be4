"""The raycast renderer's shading on Dr.Jit arrays: albedo, surface frames, the lights with
sampled soft shadows, exposure and 8-bit sRGB, in the same kernels as the exact pass (so a view
is a few kernels, on the CPU or the GPU).

Lambert on the side the camera sees: irradiance of the scene's lights (see :mod:`.lights` for
their units) plus ``ambient``, times albedo (material colour x sRGB texture, bilinear in linear
light; on cut-out cards only the texels opacity keeps).

Shadows. ``samples`` rays per pixel are shared among the lights, each picking a light with
probability proportional to its unshadowed contribution there (stratified: sample j draws in
stratum j of the pixel's light distribution, strata visited in an order that spreads the first
ones out), then one of 1024 points spread evenly over that light's disc. Each pixel has its own
random stream (Dr.Jit's PCG32, seeded by the view and the pixel), so an image does not depend on
the device, the batch or the order of pixels. With ``adaptive_after`` A (0 < A < samples),
pixels where each light sampled so far was either always seen or never after A samples take
that answer (each light's unshadowed irradiance times its visibility, no noise) and only the
others (penumbrae) get the rest.
"""

from __future__ import annotations

from typing import Any

import drjit as dr
import numpy as np

from agrisim.plugins.render.raycast.engine import Surface
from agrisim.plugins.render.raycast.lights import DISC_POINTS, LightTable
from agrisim.plugins.render.raycast.materials import SRGB_TO_LINEAR
from agrisim.plugins.render.raycast.tracing import SceneTracer
from agrisim.scene.colour import ENCODE_STEPS, LINEAR_TO_SRGB8

F32 = np.float32
_TINY = 1e-12


def progressive_order(n: int) -> list[int]:
    """The strata 0..n-1 in an order whose every prefix is spread out (by the base-2 radical
    inverse of each stratum's index)."""

    def radical_inverse(i: int) -> float:
        r, f = 0.0, 0.5
        while i:
            r += f * (i & 1)
            i >>= 1
            f *= 0.5
        return r

    return sorted(range(n), key=radical_inverse)


class Shader:
    """Shades what a :class:`SceneTracer` traced, with the scene's ``lights``."""

    def __init__(
        self, tracer: SceneTracer, lights: LightTable, *, ambient: float, bilinear: bool, epsilon: float
    ) -> None:
        self.tracer = tracer
        self.mi = mi = tracer.mi
        self.lights = lights
        self.ambient = float(ambient)
        self.bilinear = bilinear
        self.epsilon = float(epsilon)
        self.targets = mi.Float(lights.targets.reshape(-1))
        self.srgb_to_linear = mi.Float(SRGB_TO_LINEAR)
        self.encode_table = mi.UInt32(LINEAR_TO_SRGB8.astype(np.uint32))

    # ----------------------------------------------------------------- lights
    def _weights(self, p: Any, n: Any) -> list[Any]:
        """Unshadowed scalar irradiance of each light at points ``p`` with unit normals ``n``."""
        L = self.lights
        out = []
        for i in range(L.n):
            pos = L.position[i]
            to_light = self.mi.Vector3f(float(pos[0]) - p.x, float(pos[1]) - p.y, float(pos[2]) - p.z)
            r2 = dr.maximum((to_light.x * to_light.x + to_light.y * to_light.y) + to_light.z * to_light.z, _TINY)
            cos_s = dr.maximum((n.x * to_light.x + n.y * to_light.y) + n.z * to_light.z, 0.0)
            dx, dy, dz = (float(-v) for v in L.direction[i])
            cos_e = (to_light.x * dx + to_light.y * dy) + to_light.z * dz
            if L.kind[i] == "area":
                cos_s = cos_s * dr.maximum(cos_e, 0.0)
                r2 = r2 * r2
            else:
                inv_r = 1.0 / dr.sqrt(r2)
                cos_s = cos_s * inv_r
                if L.kind[i] == "spot":
                    x = dr.clip((cos_e * inv_r - float(L.cos_outer[i])) / float(L.width[i]), 0.0, 1.0)
                    cos_s = cos_s * ((x * x) * (3.0 - 2.0 * x))
            out.append((cos_s / r2) * float(L.power[i]))
        return out

    def _tinted(self, weights: list[Any]) -> Any:
        """Color3f: each light's scalar weight times its colour (per unit of its luminance)."""
        L = self.lights
        if L.uniform:
            total = weights[0]
            for w in weights[1:]:
                total = total + w
            return self.mi.Color3f(*(total * float(c) for c in L.tint[0]))
        acc = self.mi.Color3f(0.0)
        for i, w in enumerate(weights):
            acc = acc + self.mi.Color3f(*(float(c) for c in L.tint[i])) * w
        return acc

    def irradiance(self, p: Any, n: Any, samples: int, rng: Any, adaptive_after: int, active: Any) -> Any:
        """Color3f irradiance of the lights at points ``p`` with normals ``n`` (turned to the
        side seen), with ``samples`` shadow rays from just off the surface (0: no shadows)."""
        mi, L = self.mi, self.lights
        if not L.n:
            return mi.Color3f(0.0)
        w = self._weights(p, n)
        if samples <= 0:
            return self._tinted(w)
        origin = n * self.epsilon + p
        cum = [w[0]]
        for i in range(1, L.n):
            cum.append(cum[-1] + w[i])
        total = cum[-1]
        lit = active & (total > 0)
        order = mi.UInt32(np.array(progressive_order(samples), np.uint32))
        tint = mi.Float(L.tint.astype(F32).reshape(-1))
        adaptive = 0 < adaptive_after < samples

        def sample(j, on, rng, acc, counts):
            stratum = mi.Float(dr.gather(mi.UInt32, order, j, on))
            light = mi.UInt32(0)
            if L.n > 1:
                u = (rng.next_float32(on) + stratum) * (total / float(samples))
                for i in range(L.n - 1):
                    light += dr.select(u >= cum[i], 1, 0)
            pick = dr.minimum(mi.UInt32(rng.next_float32(on) * DISC_POINTS), DISC_POINTS - 1)
            k = (light * DISC_POINTS + pick) * 3
            target = mi.Point3f(*(dr.gather(mi.Float, self.targets, k + c, on) for c in range(3)))
            visible = on & ~self.tracer.occluded(origin, target - origin, on)
            v = dr.select(visible, 1.0, 0.0)
            if L.uniform:
                acc = acc + mi.Color3f(*(float(c) for c in L.tint[0])) * v
            else:
                acc = acc + mi.Color3f(*(dr.gather(mi.Float, tint, light * 3 + c, on) for c in range(3))) * v
            if counts is not None:  # per light: samples taken and samples that saw it
                counts = tuple(
                    c + dr.select(on & (light == i // 2) & ((i % 2 == 0) | visible), 1, 0) for i, c in enumerate(counts)
                )
            return rng, acc, counts

        def run(first: int, last: int, on: Any, rng: Any, acc: Any, counts: Any) -> tuple[Any, Any, Any]:
            def body(j, rng, acc, *counts):
                rng, acc, counts = sample(j, on, rng, acc, counts if counts else None)
                return (j + 1, rng, acc, *(counts or ()))

            state = (mi.UInt32(first), rng, acc, *(counts or ()))
            out = dr.while_loop(state, lambda j, *_: j < last, body, label="agrisim_shadows")
            return out[1], out[2], (out[3:] or None)

        acc = mi.Color3f(0.0)
        if not adaptive:
            rng, acc, _ = run(0, samples, lit, rng, acc, None)
            return acc * (total / float(samples))
        counts = tuple(mi.UInt32(0) for _ in range(2 * L.n))  # (tried, seen) of each light
        rng, acc, counts = run(0, adaptive_after, lit, rng, acc, counts)
        tried, seen = counts[0::2], counts[1::2]
        mixed = mi.Bool(False)
        for i in range(L.n):
            mixed |= (seen[i] > 0) & (seen[i] < tried[i])
        # Settled points: every light sampled was always seen or never; lights not sampled yet
        # count as seen as often as the others were.
        all_seen, all_tried = seen[0], tried[0]
        for i in range(1, L.n):
            all_seen, all_tried = all_seen + seen[i], all_tried + tried[i]
        frac = mi.Float(all_seen) / mi.Float(dr.maximum(all_tried, 1))
        early = [
            w[i] * dr.select(tried[i] > 0, mi.Float(seen[i]) / mi.Float(dr.maximum(tried[i], 1)), frac)
            for i in range(L.n)
        ]
        early = self._tinted(early)
        rng, acc, _ = run(adaptive_after, samples, lit & mixed, rng, acc, None)
        sampled = acc * (total / float(samples))
        return dr.select(mixed, sampled, early)

    # ---------------------------------------------------------------- shading
    def radiance(self, o: Any, d: Any, s: Surface, samples: int, rng: Any, adaptive_after: int) -> Any:
        """Color3f linear radiance of the kept surfaces ``s`` of rays (``o``, ``d``); 0 where
        nothing was hit."""
        mi, e = self.mi, self.tracer.engine
        tri = s.face >= 0
        hit = s.hit
        albedo = e.m.albedo(e.uv(s.face, s.b, tri), e.material(s.face, tri), self.bilinear, tri)
        if e.has_colors:
            albedo *= e.color(s.face, s.b, tri)
        p = d * s.t + o
        n = e.normal(s.face, tri)
        pts = self.tracer.points
        if s.point is not None:  # spheres: the point's own colour and the sphere's normal
            on = s.point >= 0
            rgb = pts.color_dr(s.point, on)
            point_albedo = mi.Color3f(*(dr.gather(mi.Float, self.srgb_to_linear, c, on) for c in rgb))
            albedo = dr.select(on, point_albedo, albedo)
            n = dr.select(on, pts.normal_dr(s.point, p, on), n)
        n = dr.select(dr.dot(n, d) > 0, -n, n)  # the side seen
        irradiance = self.irradiance(p, n, samples, rng, adaptive_after, hit) + self.ambient
        return dr.select(hit, albedo * irradiance, 0.0)

    def encode(self, linear: Any, exposure: float, reinhard: bool) -> list[Any]:
        """UInt32 8-bit sRGB levels (r, g, b) of linear RGB: times ``exposure``, optionally
        ``x / (1 + x)``, quantised to ENCODE_STEPS + 1 levels (clipped, rounded half up) and
        looked up; NaN reads level 0."""
        mi = self.mi
        out = []
        for c in range(3):
            x = linear[c]
            if exposure != 1.0:
                x = x * exposure
            if reinhard:
                x = x / (1.0 + x)
            x = dr.clip(x * float(ENCODE_STEPS), 0.0, float(ENCODE_STEPS)) + 0.5
            i = dr.select(dr.isnan(x), 0, dr.minimum(mi.UInt32(x), ENCODE_STEPS))
            out.append(dr.gather(mi.UInt32, self.encode_table, i))
        return out
