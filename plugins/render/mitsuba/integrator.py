"""``cutout_path``: Mitsuba's unidirectional path tracer, with cut-out texels passed exactly.

Mitsuba's ``path`` meets a cut-out texel (a ``mask`` BSDF of opacity 0) as a surface: the path
spends one of its vertices passing it (a leafy canopy of cards can use up ``max_depth`` before the
light is reached), and its shadow rays stop there (Embree and OptiX know triangles, not texels),
so the ground under a fern frond is lit only by the rare bounce that finds a small lamp through
the holes: slow to converge, with fireflies. ``volpath`` treats the texels as null interactions,
correctly, at 2.2x the time on an H100.

This integrator walks every ray (camera, bounce and shadow) past the texels the label pass cuts,
as :meth:`agrisim.plugins.render.raycast.engine.Engine.trace` does: a loop of ray casts with one
opacity lookup per layer, no shading, no path vertex spent (each layer is a whole ray cast, so a
fern's canopy is what the integrator pays for: bench/mitsuba_walk_cost.py). The rest is ``path``'s
algorithm (next event estimation and BSDF sampling combined by multiple importance sampling,
Russian roulette from ``rr_depth``). Masks here are 0 or 1 texel by texel (nearest filtering of
the label pass's test, :mod:`.materials`), so walking is exact, not stochastic.

With ``guide`` it also returns the denoiser's guides in the same samples: the albedo and the
shading normal of the first surface each camera ray keeps (the hole's far side where a ray
passes a cut-out, which the ``aov`` integrator, seeing the card, gets wrong), averaged over the
pixel as the radiance is.
"""

from __future__ import annotations

from typing import Any

import drjit as dr
import mitsuba as mi  # (a module global: dr.syntax rewrites the methods and drops closures)

#: the guide channels (AOVs) the integrator adds with ``guide``: albedo, then normal
GUIDE_CHANNELS = ["albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z"]
#: Mitsuba's name of the integrator
NAME = "cutout_path"

_registered: set[str] = set()


def register() -> None:
    """Make ``cutout_path`` loadable in Mitsuba's current variant (once per variant)."""
    variant = mi.variant()
    if variant in _registered:
        return
    cls = _integrator_class()
    mi.register_integrator(NAME, lambda props: cls(props))
    _registered.add(variant)


def mis_weight(pdf_a: Any, pdf_b: Any) -> Any:
    """The power heuristic's weight of a sample of density ``pdf_a`` against ``pdf_b``."""
    a2 = dr.square(pdf_a)
    return dr.detach(dr.select(pdf_a > 0, a2 / dr.fma(pdf_b, pdf_b, a2), 0))


def _integrator_class() -> type:
    """The integrator's class, derived from the current variant's ``SamplingIntegrator``."""

    class CutoutPath(mi.SamplingIntegrator):  # type: ignore[misc,name-defined]
        """Path tracing that walks past cut-out texels (see the module)."""

        def __init__(self, props: Any) -> None:
            super().__init__(props)
            self.max_depth = int(props.get("max_depth", 8))
            self.rr_depth = int(props.get("rr_depth", 5))
            self.max_layers = int(props.get("max_layers", 16))
            self.guide = bool(props.get("guide", False))

        def aov_names(self) -> list[str]:
            return list(GUIDE_CHANNELS) if self.guide else []

        def to_string(self) -> str:
            return f"CutoutPath[max_depth={self.max_depth}, rr_depth={self.rr_depth}, guide={self.guide}]"

        @staticmethod
        def _may_cut(pi: Any, active: Any) -> Any:
            """Bool: is the preliminary hit ``pi`` on a shape whose BSDF cuts texels (a ``mask``)?
            Hits on other shapes skip the opacity lookup and its surface interaction."""
            active = active & pi.is_valid()
            flags = dr.select(active, pi.shape.bsdf().flags(), 0)
            return active & mi.has_flag(flags, mi.BSDFFlags.Null)

        @staticmethod
        def _cut(si: Any, active: Any) -> Any:
            """Bool: is the hit a texel the label pass cuts (null transmission 1)?"""
            return active & (si.bsdf().eval_null_transmission(si, active).x > 0.5)

        @dr.syntax
        def _kept(self, scene: Any, ray: Any, active: Any, coherent: bool = False) -> tuple[Any, Any]:
            """(preliminary hit, ray that found it) of the first surface along ``ray`` that is
            not a cut-out texel: the surface interaction is computed where it is used, so
            that loops carry a few registers, not a whole interaction (GPUs spill them)."""
            pi = scene.ray_intersect_preliminary(ray, coherent=coherent, active=active)
            walk = self._may_cut(pi, active)
            layer = mi.UInt32(0)
            while walk:
                hit = pi.compute_surface_interaction(ray, mi.RayFlags.Minimal | mi.RayFlags.UV)
                walk = self._cut(hit, walk) & (layer < self.max_layers)
                if walk:
                    ray = hit.spawn_ray(ray.d)
                    pi = scene.ray_intersect_preliminary(ray)
                    layer += 1
                    walk = self._may_cut(pi, walk)
            return pi, ray

        @dr.syntax
        def _visible(self, scene: Any, ray: Any, target: Any, active: Any) -> Any:
            """Bool: does the shadow ray ``ray`` reach ``target`` through cut-out texels alone?
            Past ``max_layers`` cut cards the point counts as shadowed."""
            # (no any-hit test first: a blocked ray would need the closest hit after it anyway)
            blocked = mi.Bool(active)
            walk = mi.Bool(active)
            layer = mi.UInt32(0)
            while walk:
                pi = scene.ray_intersect_preliminary(ray)
                blocked = pi.is_valid()
                walk = self._may_cut(pi, blocked)
                if walk:
                    hit = pi.compute_surface_interaction(ray, mi.RayFlags.Minimal | mi.RayFlags.UV)
                    walk = self._cut(hit, walk) & (layer < self.max_layers)
                    if walk:
                        ray = hit.spawn_ray_to(target)
                        layer += 1
            return active & ~blocked

        @dr.syntax
        def sample(
            self, scene: Any, sampler: Any, ray: Any, medium: Any = None, active: Any = True
        ) -> tuple[Any, Any, list[Any]]:
            active = mi.Bool(active)
            ctx = mi.BSDFContext()
            depth = mi.UInt32(0)
            L = mi.Spectrum(0.0)
            beta = mi.Spectrum(1.0)
            eta = mi.Float(1.0)
            prev_si = dr.zeros(mi.Interaction3f)
            prev_pdf = mi.Float(1.0)
            prev_delta = mi.Bool(True)
            pi, ray = self._kept(scene, mi.Ray3f(ray), active, coherent=True)
            valid = active & pi.is_valid()
            aovs: list[Any] = []
            if dr.hint(self.guide, mode="scalar"):
                si = pi.compute_surface_interaction(ray, mi.RayFlags.All, valid)
                albedo = si.bsdf(ray).eval_diffuse_reflectance(si, valid)
                albedo = dr.select(valid, dr.clip(albedo, 0.0, 1.0), 0.0)
                normal = dr.select(valid, si.sh_frame.n, 0.0)
                aovs = [albedo.x, albedo.y, albedo.z, normal.x, normal.y, normal.z]

            while dr.hint(active, max_iterations=self.max_depth, label="agrisim_cutout_path"):
                si = pi.compute_surface_interaction(ray, mi.RayFlags.All)
                bsdf = si.bsdf(ray)

                # light reached by the previous bounce (or seen directly), weighted against
                # what emitter sampling at the previous vertex would have found
                ds = mi.DirectionSample3f(scene, si=si, ref=prev_si)
                em_pdf = scene.pdf_emitter_direction(prev_si, ds, ~prev_delta)
                Le = ds.emitter.eval(si, prev_pdf > 0)
                L += beta * mis_weight(prev_pdf, em_pdf) * Le

                active_next = (depth + 1 < self.max_depth) & si.is_valid()

                # next event estimation (its shadow ray traced below, once si is no longer live)
                active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
                ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(), False, active_em)
                active_em &= ds.pdf != 0.0
                wo = si.to_local(ds.d)
                sample1, sample2 = sampler.next_1d(), sampler.next_2d()
                bsdf_val, bsdf_pdf, bs, bsdf_weight = bsdf.eval_pdf_sample(ctx, si, wo, sample1, sample2)
                mis_em = dr.select(ds.delta, 1.0, mis_weight(ds.pdf, bsdf_pdf))
                Lem = beta * bsdf_val * em_weight * mis_em
                shadow = si.spawn_ray_to(ds.p)
                target = ds.p

                # the next vertex, by the BSDF's sample
                ray = si.spawn_ray(si.to_world(bs.wo))
                beta *= bsdf_weight
                eta *= bs.eta
                prev_si = mi.Interaction3f(si)
                prev_pdf = bs.pdf
                prev_delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
                depth[si.is_valid()] += 1

                L[self._visible(scene, shadow, target, active_em)] += Lem

                beta_max = dr.max(beta)
                rr_prob = dr.minimum(beta_max * dr.square(eta), 0.95)
                rr_active = depth >= self.rr_depth
                rr_continue = sampler.next_1d() < rr_prob
                beta[rr_active] *= dr.rcp(rr_prob)
                active = active_next & (~rr_active | rr_continue) & (beta_max != 0.0)
                pi, ray = self._kept(scene, ray, active)

            return L, valid, aovs

    return CutoutPath
