"""The ``mitsuba`` renderer (CPU, LLVM variant, small images).

Independent truths: the pinhole projection of K (emissive markers' centroids), the raycast
renderer (labels, depth and instances must be its bytes), a closed form (an integrating sphere's
indirect light), a high-sample render of the same view (error falls with samples).
"""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.lab.room import build_scene
from agrisim.config import RenderConfig
from agrisim.errors import ConfigError
from agrisim.plugins.plants.procedural import grow
from agrisim.plugins.render.mitsuba.options import MitsubaOptions
from agrisim.plugins.render.mitsuba.camera import sensor_dict
from agrisim.plugins.render.mitsuba.scene import light_dict
from agrisim.plugins.render.mitsuba.variant import newest_libllvm, resolve_variant, use_variant
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.renderer import RaycastRenderer
from agrisim.scene.camera import CameraModel
from agrisim.scene.colour import linear_to_srgb, srgb_to_linear
from agrisim.scene.model import LEAF_TRANSMITTANCE, LabelTable, Light, Material, Mesh, Scene
from agrisim.scene.transforms import look_at

try:
    resolve_variant("llvm")
    HAVE_LLVM = True
except ConfigError:
    HAVE_LLVM = False
pytestmark = pytest.mark.skipif(not HAVE_LLVM, reason="Mitsuba's LLVM variant is not usable here")


def mitsuba():  # noqa: ANN201
    return use_variant("llvm")


def renderer(scene: Scene, cell=None, **options):  # noqa: ANN001, ANN201
    from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer

    settings = {k: options.pop(k) for k in list(options) if k in RenderConfig.model_fields}
    settings.setdefault("hide_robots", cell is None)
    options.setdefault("variant", "llvm")
    return MitsubaRenderer(scene, cell, RenderConfig(**settings), MitsubaOptions(**options))


def quad(name: str, centre, half_u, half_v, material: Material) -> Mesh:
    c, a, b = (np.asarray(x, float) for x in (centre, half_u, half_v))
    v = np.array([c - a - b, c + a - b, c + a + b, c - a + b])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return Mesh(name, v, np.array([[0, 1, 2], [0, 2, 3]]), [material], np.zeros(2, np.int32), uv)


# ------------------------------------------------------------------------------ camera


@pytest.mark.parametrize("cx, cy", [(40.0, 30.0), (33.3, 27.6), (45.75, 21.2)])
def test_markers_land_on_their_k_projection(cx, cy):
    """Small emissive discs facing the camera (their images are exact circles about the
    projections of their centres) at known world points: each blob's intensity centroid is
    within 0.1 px of K's projection, for off-centre principal points too."""
    mi = mitsuba()
    camera = CameraModel(80, 60, 70.0, 70.0, cx, cy)
    T = look_at(np.array([0.3, -2.0, 1.2]), np.array([0.0, 0.0, 0.9]))
    R, t = T[:3, :3], T[:3, 3]
    targets = [(-20, -15), (18, -12), (0, 0), (-25, 18), (22, 20)]  # pixel offsets from (cx, cy)
    depths = [2.0, 2.4, 1.8, 2.2, 2.6]
    scene: dict = {"type": "scene", "integrator": {"type": "path", "max_depth": 2}}
    points = []
    for i, ((du, dv), z) in enumerate(zip(targets, depths)):
        p_cam = np.array([du / camera.fx * z, dv / camera.fy * z, z])
        p = R @ p_cam + t
        points.append(p)
        radius = 2.0 / camera.fx * z  # two pixels
        M = np.eye(4)
        M[:3, :3] = R @ np.diag([radius, radius, -radius])  # facing the camera (-z of it)
        M[:3, 3] = p
        scene[f"m{i}"] = {"type": "disk", "to_world": mi.ScalarTransform4f(M), "emitter": {"type": "area", "radiance": 1.0}}
    sensor = sensor_dict(camera, T, 512)
    sensor["to_world"] = mi.ScalarTransform4f(sensor["to_world"])
    image = np.asarray(mi.render(mi.load_dict(scene), sensor=mi.load_dict(sensor), seed=1), np.float64)[..., 0]
    for p in points:
        q = camera.K @ (R.T @ (p - t))
        u, v = q[0] / q[2], q[1] / q[2]
        r0, c0 = int(round(v)), int(round(u))
        win = image[r0 - 5 : r0 + 6, c0 - 5 : c0 + 6]
        rows, cols = np.mgrid[r0 - 5 : r0 + 6, c0 - 5 : c0 + 6]
        assert win.sum() > 5.0  # the marker is there
        cu, cv = (win * cols).sum() / win.sum(), (win * rows).sum() / win.sum()
        assert abs(cu - u) < 0.1 and abs(cv - v) < 0.1, (cu, u, cv, v)


def test_non_square_pixels_are_refused():
    with pytest.raises(ConfigError, match="square pixels"):
        sensor_dict(CameraModel(80, 60, 70.0, 72.0, 40.0, 30.0), np.eye(4), 4)


def test_newest_libllvm_of_16_or_more_is_named():
    listing = """
	libLLVM-15.so.1 (libc6,x86-64) => /lib/x86_64-linux-gnu/libLLVM-15.so.1
	libLLVM.so.19.1 (libc6,x86-64) => /lib/x86_64-linux-gnu/libLLVM.so.19.1
	libLLVM-17.so (libc6,x86-64) => /usr/lib/llvm-17/lib/libLLVM-17.so
	libLLVM-14.so (libc6,x86-64) => /lib/x86_64-linux-gnu/libLLVM-14.so
"""
    assert newest_libllvm(listing) == "/lib/x86_64-linux-gnu/libLLVM.so.19.1"
    assert newest_libllvm("\tlibLLVM-15.so.1 (libc6,x86-64) => /lib/libLLVM-15.so.1\n") is None


# ------------------------------------------------------------------------------ exact pass


@pytest.fixture(scope="module")
def lab_scene(cell):  # noqa: ANN001, ANN201
    return build_scene(cell, grow("hydrangea", 3), labels="organs")


@pytest.mark.parametrize("seg_mode", ["texture", "repopa"])
def test_labels_depth_instances_are_raycasts_bytes(cell, kin, lab_scene, seg_mode):
    """The lab with a plant and both arms, seen past an arm: labels, depth and leaf instances
    are byte for byte the raycast renderer's; the RGB differs (it is path traced)."""
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    camera = CameraModel(96, 72, 80.0, 80.0, 47.5, 35.5)
    target = lab_scene.mesh("plant").vertices.mean(axis=0)
    T = look_at(target + np.array([0.9, -0.9, 0.6]), target)
    settings = RenderConfig(seg_mode=seg_mode, labels="organs")
    ray = RaycastRenderer(lab_scene, cell, settings, RaycastOptions()).render(camera, T, poses)
    mit = renderer(lab_scene, cell, seg_mode=seg_mode, labels="organs", spp=4).render(camera, T, poses)
    assert len(np.unique(ray.labels)) > 2 and ray.instances is not None and ray.instances.max() > 1
    np.testing.assert_array_equal(mit.labels, ray.labels)
    np.testing.assert_array_equal(mit.depth, ray.depth)
    np.testing.assert_array_equal(mit.instances, ray.instances)
    assert mit.rgb.shape == ray.rgb.shape and (mit.rgb != ray.rgb).any()


# ------------------------------------------------------------------------------ light


def sphere_radiance(albedo: float, light: Light, max_depth: int, spp: int) -> np.ndarray:
    """Radiance seen from inside a closed sphere of Lambertian (Mitsuba ``diffuse``) walls lit by
    ``light`` as the renderer converts it."""
    import trimesh

    mi = mitsuba()
    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [albedo] * 3}}})
    walls = mi.Mesh("sphere", len(m.vertices), len(m.faces), props=props)
    params = mi.traverse(walls)
    params["vertex_positions"] = mi.Float(np.asarray(m.vertices, np.float32).ravel())
    params["faces"] = mi.UInt32(np.asarray(m.faces, np.uint32).ravel())
    params.update()
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth},
        "walls": walls,
        "lamp": light_dict(light, mi.ScalarTransform4f),
    }
    camera = CameraModel(32, 24, 40.0, 40.0, 15.5, 11.5)
    sensor = sensor_dict(camera, look_at(np.array([0.0, 0.3, -0.2]), np.array([0.0, 0.2, -1.0])), spp)
    sensor["to_world"] = mi.ScalarTransform4f(sensor["to_world"])
    return np.asarray(mi.render(mi.load_dict(scene), sensor=mi.load_dict(sensor), seed=3), np.float64)[..., :3]


def test_integrating_sphere_reaches_its_closed_form():
    """Inside a closed sphere of Lambertian walls (albedo a, area A), the light bounced off the
    walls is the same everywhere: irradiance a Phi / (A (1 - a)). A wall the lamp does not light
    directly (the lamp faces up; the camera looks down) then shows radiance a E / pi. An area
    light of raycast intensity I is a Lambertian disc of axial intensity pi I, so of power
    Phi = pi^2 I: the wall's radiance is pi a^2 I / (A (1 - a)). Path tracing reaches it within a
    few percent; direct light alone (max_depth 2) leaves that wall black."""
    a, intensity = 0.8, 2.0
    light = Light("lamp", "area", np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), (1.0, 1.0, 1.0), intensity, 0.05)
    import trimesh

    area = trimesh.creation.icosphere(subdivisions=4, radius=1.0).area  # its facets lie just inside
    expected = np.pi * a * a * intensity / (area * (1.0 - a))
    value = sphere_radiance(a, light, max_depth=100, spp=256).mean()
    assert abs(value / expected - 1.0) < 0.04, (value, expected)
    assert sphere_radiance(a, light, max_depth=2, spp=16).mean() < 0.01 * expected


def test_back_lit_leaf_glows_green():
    """A leaf card between the camera and a lamp behind it: the side the camera sees is lit
    only through the leaf. It is far brighter than an opaque black card there, and greenish
    (PROSPECT-D: a leaf transmits green, little blue)."""
    lamp = Light("lamp", "area", np.array([0.0, 1.0, 1.0]), np.array([0.0, -1.0, 0.0]), (1.0, 1.0, 1.0), 2.0, 0.2)
    camera = CameraModel(32, 24, 30.0, 30.0, 15.5, 11.5)
    T = look_at(np.array([0.0, -1.0, 1.0]), np.array([0.0, 0.0, 1.0]))
    leaf = Material("leaf", color=(0.05, 0.14, 0.04, 1.0), transmittance=LEAF_TRANSMITTANCE, roughness=0.4)
    black = Material("black", color=(0.0, 0.0, 0.0, 1.0))
    glow = {}
    for mat in (leaf, black):
        card = quad("card", (0.0, 0.0, 1.0), (0.3, 0.0, 0.0), (0.0, 0.0, 0.3), mat)
        image = renderer(Scene([card], [lamp], LabelTable()), spp=64, max_depth=4).radiance(camera, T)
        glow[mat.name] = image[8:16, 12:20].reshape(-1, 3).mean(axis=0)
    r, g, b = glow["leaf"]
    assert g > 0.01 and glow["black"].max() < 0.05 * g
    assert g > 1.3 * r > 0 and g > 5.0 * b


# ------------------------------------------------------------------------------ sampling


def small_lab_view(lab_scene):  # noqa: ANN001, ANN201
    camera = CameraModel(48, 36, 40.0, 40.0, 23.5, 17.5)
    target = lab_scene.mesh("plant").vertices.mean(axis=0)
    return camera, look_at(target + np.array([0.7, -0.7, 0.5]), target)


@pytest.fixture(scope="module")
def reference(lab_scene):  # noqa: ANN001, ANN201
    """A 512-sample render of the small lab view, other seed."""
    camera, T = small_lab_view(lab_scene)
    return renderer(lab_scene, spp=512, seed=7, denoise="off").radiance(camera, T)


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root-mean-square difference of two radiance images as displayed (clipped, sRGB): what
    the PNGs show, where a lamp's radiance of hundreds does not swamp the rest."""
    shown = lambda x: linear_to_srgb(np.clip(x, 0.0, 1.0))  # noqa: E731
    return float(np.sqrt(((shown(a) - shown(b)) ** 2).mean()))


def test_error_falls_as_samples_rise(lab_scene, reference):
    camera, T = small_lab_view(lab_scene)
    errors = [rmse(renderer(lab_scene, spp=s, denoise="off").radiance(camera, T), reference) for s in (2, 8, 32)]
    assert errors[0] > 1.5 * errors[1] > 2.25 * errors[2], errors


def test_denoising_brings_few_samples_closer_to_the_reference(lab_scene, reference):
    """OIDN guided by albedo and normals: 8 denoised samples are nearer the 512-sample render
    than 8 raw ones (by a wide margin) while the mean brightness stays."""
    camera, T = small_lab_view(lab_scene)
    raw = renderer(lab_scene, spp=8, denoise="off").radiance(camera, T)
    clean = renderer(lab_scene, spp=8, denoise="on").radiance(camera, T)
    assert rmse(clean, reference) < 0.6 * rmse(raw, reference)
    assert abs(clean.mean() / reference.mean() - 1.0) < 0.05


def test_same_seed_same_image_other_seed_other_noise(lab_scene):
    camera, T = small_lab_view(lab_scene)
    one = renderer(lab_scene, spp=4).render(camera, T, {})
    again = renderer(lab_scene, spp=4).render(camera, T, {})
    other = renderer(lab_scene, spp=4, seed=1).render(camera, T, {})
    np.testing.assert_array_equal(one.rgb, again.rgb)
    assert (one.rgb != other.rgb).any()
    np.testing.assert_array_equal(one.labels, other.labels)


def test_area_light_radiance_keeps_raycast_units():
    """An area light of intensity I and radius r has radiance I / r^2: its power pi I is what a
    Lambertian disc of axial intensity pi I emits (raycast's I, times pi for radiance = a E / pi)."""
    mi = mitsuba()
    light = Light("l", "area", np.zeros(3), np.array([0.0, 0.0, -1.0]), (1.0, 0.5, 0.25), 3.0, 0.2)
    d = light_dict(light, mi.ScalarTransform4f)
    assert np.allclose(d["emitter"]["radiance"]["value"], np.array([1.0, 0.5, 0.25]) * 3.0 / 0.04)
    M = np.array(d["to_world"].matrix)
    assert np.allclose(M[:3, 2] / np.linalg.norm(M[:3, 2]), [0.0, 0.0, -1.0])  # faces its direction
    assert np.allclose(np.linalg.norm(M[:3, :3], axis=0), 0.2)


def test_environment_map_lights_what_the_camera_sees_of_the_sky(tmp_path):
    """A uniform environment map (an sRGB PNG of one colour) seen where nothing else is: the
    pixels are its linear radiance times ``envmap_scale``; scaled twice, twice as bright."""
    from PIL import Image

    path = tmp_path / "sky.png"
    Image.fromarray(np.full((16, 32, 3), (128, 160, 200), np.uint8)).save(path)
    expected = srgb_to_linear(np.array([128, 160, 200]) / 255.0)
    camera = CameraModel(16, 12, 14.0, 14.0, 7.5, 5.5)
    T = look_at(np.zeros(3), np.array([1.0, 0.0, 0.2]))
    empty = Scene([], [], LabelTable())
    sky = renderer(empty, spp=4, envmap=path, denoise="off").radiance(camera, T)
    np.testing.assert_allclose(sky.reshape(-1, 3).mean(axis=0), expected, rtol=0.02)
    brighter = renderer(empty, spp=4, envmap=path, envmap_scale=2.0, denoise="off").radiance(camera, T)
    np.testing.assert_allclose(brighter.mean(), 2.0 * sky.mean(), rtol=1e-4)
