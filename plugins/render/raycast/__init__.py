"""The ``raycast`` renderer: Open3D's ``RaycastingScene`` (Embree, CPU) with alpha-tested cards.

One primary pass gives RGB, labels and depth together: a ray through each pixel centre (OpenCV:
direction ``K^-1 [u, v, 1]`` rotated to the world, so the hit distance in units of that direction
*is* the planar z of the hit).

Opacity. Embree knows nothing of textures, so a hit on a texel that opacity cuts away (a
``MASK``/``BLEND`` material whose albedo alpha is below its cutoff, compared in 8 bits exactly as
:func:`agrisim.scene.texturing.opaque`) is passed here: the ray is cast again from just past that hit
(``epsilon`` m along it), up to ``max_layers`` surfaces; rays still on cut-out texels after that
count as hitting nothing. Back faces of single-sided materials are passed the same way (glTF back
face culling). RGB and depth come from the first surface that is left.

Labels. Only the plant mesh (``scene.plant``) carries labels; its label texture is sampled
*nearest* at the hit's UV (the texel :func:`agrisim.scene.texturing.label_at` names).
``seg_mode="texture"`` labels the first opaque hit (the paper's method); ``seg_mode="repopa"``
ignores opacity for labels only (EasySynth's way): the first hit of any card decides, a cut-out
texel taking its label texture's value there or, where that is 0, the material's most common
non-zero label. ``labels="plant"`` maps every non-zero id to 1. Leaf instance ids
(``Mesh.face_instance``) come with the labels' hits.

Shading (see :mod:`agrisim.plugins.render.raycast.lights`). Lambert on the side the camera sees, with the
scene's lights plus ``ambient``, albedo (material colour x sRGB texture, ``texture_filter``) in
linear light, ``exposure`` and a tone map back to sRGB. ``shadow_samples`` N rays per pixel are shared
among the lights; shadow rays pass cut-out texels like primary rays (light falls through the
holes of cards). Sampling is seeded from ``seed`` and the view, so the same inputs give
byte-identical images; N = 0 is hard-lit without shadows. With ``supersample`` s > 1, RGB is the
mean of s x s rays per pixel (each with ``ceil(N / s^2)`` shadow rays); labels and depth stay
exact at the pixel centres.

Points. A point plant (``Scene.points``) is drawn as spheres of its point size, traced exactly
by Mitsuba's ``ellipsoids`` shape (:mod:`.points`) beside Open3D's triangles; the nearer hit wins.
A sphere's label, instance and colour are its point's; its depth is that of the sphere's
surface; it is shaded with the sphere's normal and casts and receives shadows.

Arms. Their visual meshes are loaded once (decimated to ``arm_triangles``) and placed per frame
at ``link_poses``. Embree has no instancing here, so the posed arms are rebuilt whenever the poses
change, together with the static scene when it is small (one cast per ray), else in a scene of
their own (the nearer hit of the two wins).

Performance: Open3D casts on all cores but holds the GIL; everything between the casts runs on
tiles of whole image rows (``tile_pixels``), in ``workers`` threads. Every ray cast is batched (a
tile's rays, then the ever fewer rays going on past cut-out texels), so Python never loops over
pixels. The per-pixel arithmetic (texture coordinates, bilinear albedo, hit points and normals,
the lights' unshadowed irradiance, 8-bit encoding) runs in compiled loops that release the GIL
(:mod:`.kernels`, Numba), so one tile shades while another's rays are cast; the rest is float32
numpy in chunks of ``lights.CHUNK`` pixels. With more than ``adaptive_after`` shadow samples,
only penumbra pixels get them all. On the lab at 1080p a view's ~2M primary and ~2M shadow rays
take about two thirds of its time in Embree (``bench/accounting.py`` splits it).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.capabilities import SEG_MODES, RendererCapabilities
from agrisim.kinds import lazy



class RaycastOptions(Options):
    """Options of the raycast (Open3D/Embree) renderer."""

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
    background: tuple[int, int, int] = (0, 0, 0)
    """sRGB colour of pixels that hit nothing."""
    arm_triangles: int = Field(30000, ge=0, le=10_000_000)
    """Triangles per arm after quadric decimation of its visual meshes (0: as loaded; the UR10's
    have 116k). Fewer make the per-frame rebuild of the posed arms cheaper."""
    merge_limit: int = Field(10_000, ge=0, le=100_000_000)
    """Static scenes of up to this many triangles are rebuilt with the posed arms into one Embree
    scene (one cast per ray instead of two); larger ones stay in a scene of their own (measured
    in the lab at 1080p: merging saves ~8% with a 2k-triangle plant and costs ~10% with a 62k
    one, whose rebuild per pose takes longer and whose shadow rays blocked by the arms would
    walk the plant's cut-out texels too)."""
    threads: int = Field(0, ge=0, le=1024)
    """Embree threads per ray batch (0: all cores)."""
    workers: int = Field(0, ge=0, le=64)
    """Image tiles shaded in parallel threads (0: one per core). Results do not depend on it."""
    tile_pixels: int = Field(1 << 18, ge=1024, le=1 << 26)
    """Pixels per tile (whole rows): bounds memory, keeps numpy's working set in cache. Each tile
    has its own random stream, so changing it changes the shadow noise (not its statistics)."""


@hookimpl
def agrisim_renderers() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="raycast",
            factory=lazy('agrisim.plugins.render.raycast.renderer:RaycastRenderer'),
            description="Open3D RaycastingScene (Embree, CPU): exact depth and texture labels, alpha-tested cards, "
            "soft shadows",
            options_model=RaycastOptions,
            limits="Lambert shading with direct light and an ambient term (no indirect light, no specular); "
            "no texture mipmaps; alpha is a step at the cutoff (no blending)",
            capabilities=RendererCapabilities(
                seg_modes=frozenset(SEG_MODES),
                organ_labels=True,
                leaf_instances=True,
                soft_shadows=True,
                supersampling=True,
                points=True,
            ),
        )
    ]
