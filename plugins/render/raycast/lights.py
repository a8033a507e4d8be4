"""Direct lighting at surface points: the scene's lights as arrays, Lambert, sampled shadows.

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

from collections.abc import Callable, Iterator

import numpy as np

from agrisim.plugins.render.raycast.kernels import AREA, POINT, SPOT, light_weights
from agrisim.scene.model import Light

F32 = np.float32
#: shadow rays stop this fraction of their length short of the light (a lamp's own housing
#: must not shadow it): ``occluded`` tests the segment up to ``SHADOW_TFAR`` of its length
SHADOW_TFAR = 1.0 - 1e-3
#: points per area light that shadow rays aim at
DISC_POINTS = 1024
#: points whose per-point arithmetic runs together (here and in the renderer): the scratch
#: arrays of a chunk stay in cache, and each numpy call still does enough work that the two
#: worker threads, which hand the GIL to each other between calls, are seldom kept waiting
CHUNK = 1 << 15


class LightTable:
    """The scene's lights as arrays, and their irradiance at surface points."""

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
        # for the compiled weights (kernels.light_weights): kinds as numbers, spot cone widths
        self.kind_code = np.array([{"area": AREA, "spot": SPOT}.get(k, POINT) for k in self.kind], np.int8)
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

    def weights(self, p: np.ndarray, n: np.ndarray, out: np.ndarray | None = None, origins: np.ndarray | None = None, eps: float = 0.0) -> np.ndarray:
        """Unshadowed scalar irradiance (L x K) of each light at points ``p`` (3 x K, one row per
        coordinate) with unit normals ``n`` (3 x K) (from the centre of area lights; the mean of
        each light's colour); with ``origins`` (3 x K) also the shadow rays' origins ``p + eps n``
        there. Compiled: :func:`~agrisim.plugins.render.raycast.kernels.light_weights`."""
        k = p.shape[1]
        w = np.empty((self.n, k), F32) if out is None else out
        none = np.empty((3, 0), F32)
        light_weights(
            p, n, self.position, self.direction, self.kind_code, self.power, self.cos_inner, self.cos_outer,
            self.width, F32(eps), w, none if origins is None else origins,
        )
        return w

    # The shadow-sampling kernel: chunked, vectorised and adaptive in one loop so that its scratch arrays stay in cache.
    def irradiance(
        self,
        w: np.ndarray,
        origins: np.ndarray | None,
        samples: int,
        rng: np.random.Generator,
        occluded: Callable[[np.ndarray], np.ndarray],
        adaptive_after: int = 0,
    ) -> np.ndarray:
        """Irradiance (3 x K: rows of R, G and B) at points whose unshadowed :meth:`weights` are
        ``w`` (L x K; overwritten), with ``samples`` shadow rays per point (0: no shadows).
        Shadow rays start at ``origins`` (3 x K, just off each surface); ``occluded(rays)``
        answers whether each ray (M x 6: origin, origin-to-light segment) is blocked before
        ``SHADOW_TFAR``.

        Sample j picks its light in stratum j of the points' light distribution (strata visited
        in an order that spreads the first ones out), so each light gets its share of the rays.
        With ``adaptive_after`` A (0 < A < samples), points where each light sampled so far was
        either always seen or never after A samples take that answer (each light's unshadowed
        irradiance times its visibility, no noise) and only the others (penumbrae) get the rest.

        The random numbers of a sample are drawn for all its points at once (the stream does not
        depend on chunking); the arithmetic around them runs chunk by chunk (``CHUNK`` points),
        as large temporaries cost page faults as well as cache misses.
        """
        k = w.shape[1]
        if not self.n:
            return np.zeros((3, k), F32)
        if samples <= 0:
            if self.uniform:
                return np.multiply(self.tint[0][:, None], w.sum(axis=0), dtype=F32)
            out = np.zeros((3, k), F32)
            for i in range(self.n):
                out += self.tint[i][:, None] * w[i]
            return out
        cum = w
        for i in range(1, self.n):  # cumulative over the lights (np.cumsum along axis 0 is slow)
            cum[i] += cum[i - 1]
        total = cum[-1]
        lit = np.flatnonzero(total > 0)  # the points any light reaches: the others stay black
        if not len(lit):
            return np.zeros((3, k), F32)
        every = len(lit) == k
        if not every:
            cum, total = np.take(cum, lit, axis=1), total[lit]
        m = len(lit)
        rays = np.empty((m, 6), F32)  # origins stay, segments change per sample
        for x in range(3):  # column by column: long loops (a K x 3 op loops over threes)
            rays[:, x] = origins[x] if every else np.take(origins[x], lit)
        adaptive = 0 < adaptive_after < samples
        if adaptive:  # per light: samples taken and samples that saw it
            seen = np.zeros((self.n, m), np.int16)
            tried = np.zeros((self.n, m), np.int16)
        # Sum of tint x visibility: a scalar per point when all lights have one colour, else
        # rows of R, G and B (the channels of the same points stay together in memory).
        acc = np.zeros(m if self.uniform else (3, m), F32)
        tint_rows = np.ascontiguousarray(self.tint.T)
        active = None  # all points
        rays_a = rays
        total_a = total
        for j, stratum in enumerate(_progressive_order(samples)):
            if adaptive and j == adaptive_after:
                # Points where every light sampled was always seen or never: those answers are
                # final (lights not sampled yet count as seen as often as the others were).
                mixed = ((seen > 0) & (seen < tried)).any(axis=0)
                settled = np.flatnonzero(~mixed)
                vis = seen[:, settled].astype(F32) / np.maximum(tried[:, settled], 1)
                frac = seen[:, settled].sum(axis=0) / np.maximum(tried[:, settled].sum(axis=0), 1)
                vis = np.where(tried[:, settled] > 0, vis, frac)
                lit_by = np.diff(cum[:, settled], axis=0, prepend=0.0) * vis  # each light's weight x seen
                early = (settled, lit_by.sum(axis=0) if self.uniform else np.einsum("lk,lc->ck", lit_by, self.tint))
                active = np.flatnonzero(mixed)
                if not len(active):
                    break
                cum, total_a, rays_a = np.take(cum, active, axis=1), total[active], np.take(rays, active, axis=0)
            ma = len(total_a)
            u = rng.random(ma, dtype=F32) if self.n > 1 else None
            pick = rng.integers(0, DISC_POINTS, ma, dtype=np.intp)  # a point on the light
            light = np.zeros(ma, np.uint8 if self.n < 256 else np.intp)  # (small: cheap to count into)
            for c in chunks(ma):
                lc = light[c]
                if u is not None:
                    uc = u[c]
                    uc += F32(stratum)
                    uc *= total_a[c] / F32(samples)
                    for i in range(self.n - 1):
                        lc += uc >= cum[i, c]
                which = lc.astype(np.intp)
                which *= DISC_POINTS
                which += pick[c]
                target = np.take(self.targets, which, axis=0)
                rc = rays_a[c]
                for x in range(3):  # column by column: long loops (a K x 3 op loops over threes)
                    np.subtract(target[:, x], rc[:, x], out=rc[:, 3 + x])
            visible = ~occluded(rays_a)
            if active is None and adaptive:
                cols = np.arange(ma)
                tried[light, cols] += 1
                seen[light, cols] += visible
            if self.uniform:
                if active is None:
                    acc += visible
                else:
                    acc[active] += visible
                continue
            for c in chunks(ma):
                contribution = np.take(tint_rows, light[c], axis=1)
                contribution *= visible[c]
                if active is None:
                    acc[:, c] += contribution
                else:
                    acc[:, active[c]] += contribution
        acc *= total / F32(samples)
        if adaptive and j >= adaptive_after:
            if self.uniform:
                acc[early[0]] = early[1]
            else:
                acc[:, early[0]] = early[1]
        if self.uniform:
            if not every:  # back to all points (1-D scatters: fast, unlike scattering rows)
                acc = _spread(acc, lit, k)
            return np.multiply(self.tint[0][:, None], acc, dtype=F32)
        if every:
            return acc
        out = np.zeros((3, k), F32)
        for x in range(3):
            out[x, lit] = acc[x]
        return out


def chunks(n: int) -> Iterator[slice]:
    """Slices of ``range(n)``, ``CHUNK`` long (the last one shorter)."""
    return (slice(i, min(i + CHUNK, n)) for i in range(0, n, CHUNK))


def _spread(values: np.ndarray, index: np.ndarray, k: int) -> np.ndarray:
    """A length-``k`` array of zeros with ``values`` at ``index``."""
    out = np.zeros(k, values.dtype)
    out[index] = values
    return out


def _progressive_order(n: int) -> list[int]:
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
