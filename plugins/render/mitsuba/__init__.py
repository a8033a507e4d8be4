"""The ``mitsuba`` renderer: path-traced RGB (Mitsuba 3, global illumination) on the CPU (LLVM)
or an NVIDIA GPU (CUDA/OptiX), with labels, depth and leaf instances from the raycast renderer's
exact pass, byte for byte.

What each part does:

* :mod:`.variant` picks Mitsuba's variant (``auto``: CUDA when a GPU is usable, else LLVM) and
  says clearly what is missing when neither runs (the LLVM variant needs a shared libLLVM 15+).
* :mod:`.camera` maps OpenCV's K and pose onto Mitsuba's ``perspective`` sensor exactly (its
  camera looks along +z with +x left and +y up; its film puts pixel i over [i, i + 1)).
* :mod:`.materials` turns agrisim materials into BSDFs: ``principled`` with the material's
  roughness and metallic, two-sided where the material is; translucent leaf cards as an even
  blend of that reflector and a ``principledthin`` diffuse transmitter (so reflectance and
  transmittance each keep their own colour, as PROSPECT-D's do); cut-outs as a ``mask`` whose
  opacity is the label pass's own test (8-bit alpha against the material's cutoff, nearest texel);
  glTF's metallic-roughness textures, normal maps (``normalmap``, in glTF's tangent frame) and
  diffuse transmission colours.
* :mod:`.scene` builds the Mitsuba scene: every mesh split by material, the lab's lights with
  the raycast renderer's radiometric meaning, an optional environment map, and the arms, whose
  vertices are moved to each frame's link poses.
* :mod:`.integrator` is ``cutout_path``, Mitsuba's path tracer with camera, bounce and shadow
  rays walking past cut-out texels exactly (Mitsuba's own spend a path vertex on each and stop
  shadow rays there), returning the denoiser's albedo and normal guides in the same samples.
* :mod:`.renderer` renders a view: path tracing (box filter: no pixel blurs into its
  neighbour), the linear radiance to 8-bit sRGB through the same encoder as raycast (one
  exposure for the run), and the exact pass for labels, depth and instances.

Radiometry. The raycast renderer's lights are in "white-surface units": a light of intensity I
lights a surface at distance d facing it with irradiance I / d^2, and irradiance 1 makes a white
Lambertian surface's pixel value 1. Physically a Lambertian surface of albedo a under irradiance E
has radiance a E / pi, so the same pixel values come from lights pi times stronger: an area light
(a Lambertian disc of radius r) gets radiance I / r^2 (its axial intensity L pi r^2 is then pi I),
a point or spot light intensity pi I. Direct light alone then matches raycast without its
ambient term; the light bounced off walls, floor and table is what path tracing adds.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from agrisim import BackendSpec, hookimpl
from agrisim.capabilities import SEG_MODES, RendererCapabilities
from agrisim.kinds import lazy

from .options import MitsubaOptions

if TYPE_CHECKING:
    from agrisim.config import RunConfig


def preflight(config: RunConfig, options: MitsubaOptions) -> None:
    """Refuse, before anything is written, a variant that cannot run here and an environment
    map that cannot be read."""
    from .variant import resolve_variant

    resolve_variant(options.variant)
    if options.denoise == "on":
        from .denoise import check_denoiser

        check_denoiser()
    if options.envmap is not None:
        from .scene import check_envmap

        check_envmap(options.envmap)


@hookimpl
def agrisim_renderers() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="mitsuba",
            factory=lazy("agrisim.plugins.render.mitsuba.renderer:MitsubaRenderer"),
            description="Mitsuba 3 path tracing (CPU LLVM or NVIDIA CUDA): global illumination, translucent "
            "leaves; labels, depth and instances from raycast's exact pass",
            options_model=MitsubaOptions,
            limits="needs mitsuba and drjit (the CPU variant a shared libLLVM 15+); single-sided materials show "
            "a black back face where raycast culls it; no normal maps yet",
            capabilities=RendererCapabilities(
                seg_modes=frozenset(SEG_MODES),
                organ_labels=True,
                leaf_instances=True,
                plants=True,
                soft_shadows=True,
                supersampling=True,
                rerender=True,
                lenses=True,
                radiance=True,
            ),
            preflight=preflight,
        )
    ]
