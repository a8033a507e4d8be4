"""The ``raycast`` renderer: exact ray tracing on Dr.Jit with alpha-tested cards, on the CPU
(Mitsuba's Embree, ``llvm``) or an NVIDIA GPU (OptiX, ``cuda``).

One primary pass gives RGB, labels and depth together: a ray through each pixel centre (OpenCV:
direction ``K^-1 [u, v, 1]`` rotated to the world, so the hit distance in units of that direction
*is* the planar z of the hit).

Opacity. Embree and OptiX know nothing of textures, so a hit on a texel that opacity cuts away (a
``MASK``/``BLEND`` material whose albedo alpha is below its cutoff, compared in 8 bits exactly as
:func:`agrisim.scene.texturing.opaque`) is passed: the ray goes on from just past that hit
(``epsilon`` m along it), up to ``max_layers`` surfaces, in a Dr.Jit loop inside the kernel;
rays still on cut-out texels after that count as hitting nothing. Back faces of single-sided
materials are passed the same way (glTF back face culling). RGB and depth come from the first
surface that is left.

Labels. Only the plant mesh (``scene.plant``) carries labels; its label texture is sampled
*nearest* at the hit's UV (the texel :func:`agrisim.scene.texturing.label_at` names).
``seg_mode="texture"`` labels the first opaque hit (the paper's method); ``seg_mode="repopa"``
ignores opacity for labels only (EasySynth's way): the first hit of any card decides, a cut-out
texel taking its label texture's value there or, where that is 0, the material's most common
non-zero label. ``labels="plant"`` maps every non-zero id to 1. Leaf instance ids
(``Mesh.face_instance``) come with the labels' hits.

Shading (:mod:`.shading`). Lambert on the side the camera sees, with the scene's lights plus
``ambient``, albedo (material colour x sRGB texture, ``texture_filter``, x the vertex colour
where the mesh has one) in linear light,
``exposure`` and a tone map back to sRGB. ``shadow_samples`` N rays per pixel are shared among
the lights; shadow rays pass cut-out texels like primary rays (light falls through the holes of
cards). Every pixel has its own random stream, seeded from ``seed``, the view and the pixel, so
the same inputs give byte-identical images on any batch size; N = 0 is hard-lit without
shadows. With ``supersample`` s > 1, RGB is the mean of s x s rays per pixel (each with
``ceil(N / s^2)`` shadow rays); labels and depth stay exact at the pixel centres.

Points. A point plant (``Scene.points``) is drawn as spheres of its point size, traced exactly
by Mitsuba's ``ellipsoids`` shape (:mod:`.points`) in the same kernels as the triangles; the
nearer hit wins. A sphere's label, instance and colour are its point's; its depth is that of
the sphere's surface; it is shaded with the sphere's normal and casts and receives shadows.

Arms. Their visual meshes are loaded once (decimated to ``arm_triangles``) and placed per frame
by the transforms of their instances (:mod:`.engine`): the static scene's acceleration structure
is built once.

Performance: a view is traced and shaded as a handful of Dr.Jit kernels over all its pixels
(``batch_pixels`` at a time), compiled on the first view and reused for every later one; on the
CPU they run on all cores without the GIL.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import SEG_MODES, RendererCapabilities
from agrisim.kinds import lazy


class RaycastOptions(Options):
    """Options of the raycast renderer."""

    variant: Literal["auto", "cuda", "llvm"] = "auto"
    """Where Dr.Jit traces and shades: ``cuda`` (NVIDIA GPU, OptiX), ``llvm`` (CPU, Embree; needs
    a shared libLLVM 16 or newer) or ``auto`` (CUDA when a GPU is usable, else LLVM), chosen as
    the mitsuba renderer chooses (one variant per process)."""

    shadow_samples: int = Field(1, ge=0, le=32)
    """Shadow rays per pixel shared among the lights (the paper's Raytrace Samples;
    ``--shadow-samples``); 0: none."""
    supersample: int = Field(1, ge=1, le=4)
    """RGB rays per pixel side (``--supersample``); labels and depth stay exact at pixel centres."""
    ambient: float = Field(0.15, ge=0.0, le=100.0)
    """Ambient irradiance added everywhere (a white surface lit by ambient 1 alone is white)."""
    exposure: float = Field(1.0, gt=0.0, le=1e6)
    """Scale of the linear radiance before tone mapping."""
    tonemap: Literal["clip", "reinhard"] = "clip"
    """Linear to display: ``clip`` keeps albedos exact up to white; ``reinhard`` (x / (1 + x))
    rolls highlights off smoothly."""
    texture_filter: Literal["bilinear", "nearest"] = "bilinear"
    """Albedo lookups for RGB (labels and opacity are always the nearest texel's)."""
    max_layers: int = Field(16, ge=1, le=256)
    """Most surfaces a ray meets (cut-out texels, culled back faces included) before it counts as
    a miss."""
    near: float = Field(1e-3, ge=0.0, le=1.0)
    """Near clipping plane (planar z), m: nothing closer is seen (the camera's own body)."""
    epsilon: float = Field(1e-4, gt=0.0, le=0.01)
    """Offset, m, of a ray continuing past a cut-out texel and of a shadow ray off its surface."""
    seed: int = Field(0, ge=0, le=2**32 - 1)
    """Seed of shadow sampling (mixed with the view: every view has its own streams)."""
    adaptive_after: int = Field(8, ge=0, le=32)
    """With more shadow samples than this, pixels whose first ones all agree (fully lit or fully
    shadowed) keep that answer; only the others (penumbrae) get the rest. 0: all get all."""
    radiance: bool = False
    """Also keep each view's linear radiance (before exposure and tone mapping; float32 R, G, B,
    a white surface under irradiance 1 is 1): an imager (``--imager``) makes its images from
    it, and the dataset gets ``radiance/<frame>.exr``."""
    background: tuple[int, int, int] = (0, 0, 0)
    """sRGB colour of pixels that hit nothing."""
    arm_triangles: int = Field(30000, ge=0, le=10_000_000)
    """Triangles per arm after quadric decimation of its visual meshes (0: as loaded; the UR10's
    have 116k). Fewer make the per-frame rebuild of the posed arms cheaper."""
    batch_pixels: int = Field(1 << 22, ge=1024, le=1 << 26)
    """Pixels traced and shaded together (whole rows): bounds memory at any resolution (a 1080p
    view is one batch). Results do not depend on it: every pixel has its own random stream."""


def preflight(config: object, options: RaycastOptions) -> None:
    """Refuse, before anything is written, a variant that cannot run here."""
    from agrisim.plugins.render.mitsuba.variant import resolve_variant

    resolve_variant(options.variant, "raycast")


@hookimpl
def agrisim_renderers() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="raycast",
            factory=lazy("agrisim.plugins.render.raycast.renderer:RaycastRenderer"),
            description="Exact ray tracing on Dr.Jit (Embree on the CPU, OptiX on NVIDIA GPUs): exact depth and "
            "texture labels, alpha-tested cards, soft shadows",
            options_model=RaycastOptions,
            preflight=preflight,
            limits="Lambert shading with direct light and an ambient term (no indirect light, no specular); "
            "no texture mipmaps; alpha is a step at the cutoff (no blending)",
            capabilities=RendererCapabilities(
                seg_modes=frozenset(SEG_MODES),
                organ_labels=True,
                leaf_instances=True,
                plants=True,
                soft_shadows=True,
                supersampling=True,
                points=True,
                rerender=True,
                lenses=True,
                radiance=True,
            ),
        )
    ]
