"""Leaving out of a cast the arm links that no ray of the view can meet (:mod:`.culling`):

* a box left out is one that no pixel ray meets, against an independent slab test of
  every pixel ray (with the renderer's sub-pixel offsets) on boxes around the frustum's edges;
* a raycast view (labels, depth and the shadow-lit RGB) is the same byte for byte with the arms
  culled and with every link cast, on views that leave links out and keep others.
"""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.config import RenderConfig, build_config
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.render.raycast import RaycastOptions, culling
from agrisim.plugins.render.raycast.renderer import RaycastRenderer
from agrisim.plugins.render.raycast.tracing import SceneTracer
from agrisim.plugins.rigs.paper.cell import hemisphere
from agrisim.plugins.rooms.lab.room import build_scene
from agrisim.registry import Registry, make_plugin_manager
from agrisim.scene.camera import preset

CAMERA = preset("rpi3-wide-1080p", "64x36")
NEAR = 0.01


def _hit_by_a_pixel_ray(lo: np.ndarray, hi: np.ndarray) -> bool:
    """Slab test of every pixel ray (camera at the origin looking down +z, from the near plane;
    centres and the +-0.5 pixel offsets of supersampling) against the box [lo, hi]."""
    u, v = np.meshgrid(np.arange(CAMERA.width, dtype=float), np.arange(CAMERA.height, dtype=float))
    hits = False
    for du in (-0.5, 0.0, 0.5):
        for dv in (-0.5, 0.0, 0.5):
            d = np.stack(
                [((u + du - CAMERA.cx) / CAMERA.fx).ravel(), ((v + dv - CAMERA.cy) / CAMERA.fy).ravel()], axis=1
            )
            d = np.hstack([d, np.ones((len(d), 1))])
            o = d * NEAR
            with np.errstate(divide="ignore", invalid="ignore"):
                t0, t1 = (lo - o) / d, (hi - o) / d
            near = np.nan_to_num(np.minimum(t0, t1), nan=-np.inf).max(axis=1)
            far = np.nan_to_num(np.maximum(t0, t1), nan=np.inf).min(axis=1)
            hits |= bool(((near <= far) & (far >= 0)).any())
    return hits


def test_a_box_is_left_out_only_when_no_pixel_ray_meets_it():
    frustum = culling.frustum_corners(CAMERA, np.eye(4), NEAR, 10.0)
    planes = culling.hull_planes(frustum)
    rng = np.random.default_rng(7)
    # boxes around each side of the frustum, at depths from just past the near plane to 5 m
    left_out = kept = 0
    for _ in range(1000):
        z = rng.uniform(-0.05, 5.0)
        edge_x = (rng.choice([-0.5, CAMERA.width - 0.5]) - CAMERA.cx) / CAMERA.fx * max(z, NEAR)
        edge_y = (rng.choice([-0.5, CAMERA.height - 0.5]) - CAMERA.cy) / CAMERA.fy * max(z, NEAR)
        centre = np.array([edge_x, edge_y, z]) + rng.normal(0, 0.05, 3) * [1, 1, 0.2]
        half = rng.uniform(0.001, 0.05, 3)
        lo, hi = centre - half, centre + half
        out = culling.outside(culling.box_corners(np.array([lo, hi])), planes)
        if out:
            assert not _hit_by_a_pixel_ray(lo, hi), (lo, hi)
            left_out += 1
        else:
            kept += _hit_by_a_pixel_ray(lo, hi)
    assert left_out > 50 and kept > 50, (left_out, kept)  # both sides were tried, and kept boxes were met
    # A box wholly behind the near plane is left out; one that reaches past it by a micrometre is not.
    behind = culling.box_corners(np.array([[-0.1, -0.1, -0.2], [0.1, 0.1, NEAR - 1e-5]]))
    assert culling.outside(behind, planes)
    assert not culling.outside(behind + [0, 0, 2e-5], planes)
    assert culling.hull_planes(np.zeros((8, 3))) is None  # no volume: nothing is left out
    assert not culling.outside(behind, None)


@pytest.fixture(scope="module")
def lab(cell, kin):
    scene = build_scene(cell, resolve_plant(Registry(make_plugin_manager()), build_config({"plant": "boston_fern"})))
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    return scene, poses


def test_culled_arms_change_no_pixel_of_a_shaded_view(cell, lab):
    scene, poses = lab
    camera = preset("rpi3-wide-1080p", "160x90")
    settings = RenderConfig(seg_mode="repopa", labels="organs")
    culled = RaycastRenderer(scene, cell, settings, RaycastOptions(shadow_samples=2))
    every = RaycastRenderer(scene, cell, settings, RaycastOptions(shadow_samples=2))
    every.tracer.place_arms = lambda lp, view=None: SceneTracer.place_arms(every.tracer, lp)  # type: ignore[method-assign]
    setpoints = hemisphere(cell, build_config({}).routine)
    views = [setpoints["r1"][0].world_T_camera, setpoints["r2"][40].world_T_camera, setpoints["r2"][10].world_T_camera]
    links = len(culled.tracer.engine.links)
    some_left_out = False
    for T in views:
        a = culled.render(camera, T, poses)
        shown = len(culled.tracer.engine._seen.scene.shapes()) if culled.tracer.engine._seen else 0
        some_left_out |= 0 < shown < links
        b = every.render(camera, T, poses)
        for key in ("rgb", "labels", "depth", "instances"):
            x, y = getattr(a, key), getattr(b, key)
            assert (x is None) == (y is None)
            if x is not None:
                assert np.array_equal(x, y), f"{key} differs in {(x != y).sum()} entries"
    assert some_left_out  # the views did leave links out, and kept some
