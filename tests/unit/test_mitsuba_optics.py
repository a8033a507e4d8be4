"""The mitsuba renderer's camera and light mapping, on each Mitsuba variant: ``llvm`` here and in
CI, ``cuda`` (marked ``gpu``) on the GPU machine. Only light imports (no Open3D, no trimesh), so
the GPU machine runs this module from a minimal install: ``pytest --noconftest -m gpu``.

Truths: K's projection of emissive markers, an integrating sphere's closed form.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from agrisim.errors import ConfigError
from agrisim.plugins.render.mitsuba.camera import load_sensor
from agrisim.plugins.render.mitsuba.scene import light_dict
from agrisim.plugins.render.mitsuba.variant import resolve_variant, use_variant
from agrisim.scene.camera import CameraModel
from agrisim.scene.model import Light, Material
from agrisim.scene.transforms import look_at

VARIANTS = ["llvm", pytest.param("cuda", marks=pytest.mark.gpu)]


@pytest.fixture(params=VARIANTS)
def mi(request):  # noqa: ANN001, ANN201
    """Mitsuba set to the variant; one variant per process, so a process that already renders
    with the other skips (run the GPU tests alone: ``-m gpu``)."""
    import mitsuba

    try:
        resolve_variant(request.param)
    except ConfigError as exc:
        pytest.skip(str(exc))
    current = mitsuba.variant()
    if current is not None and not current.startswith(request.param):
        pytest.skip(f"this process renders with {current}")
    return use_variant(request.param)


def render(mi, scene: dict, camera: CameraModel, T: np.ndarray, spp: int) -> np.ndarray:  # noqa: ANN001
    return np.asarray(mi.render(mi.load_dict(scene), sensor=load_sensor(mi, camera, T, spp), seed=1), np.float64)[
        ..., :3
    ]


@pytest.mark.parametrize("cx, cy", [(40.0, 30.0), (33.3, 27.6), (45.75, 21.2)])
def test_markers_land_on_their_k_projection(mi, cx, cy):  # noqa: ANN001
    """Small emissive discs facing the camera (their images are exact circles about the
    projections of their centres) at known world points: each blob's intensity centroid is
    within 0.1 px of K's projection, for off-centre principal points too."""
    camera = CameraModel(80, 60, 70.0, 70.0, cx, cy)
    T = look_at(np.array([0.3, -2.0, 1.2]), np.array([0.0, 0.0, 0.9]))
    R, t = T[:3, :3], T[:3, 3]
    targets = [(-20, -15), (18, -12), (0, 0), (-25, 18), (22, 20)]  # pixel offsets from (cx, cy)
    depths = [2.0, 2.4, 1.8, 2.2, 2.6]
    scene: dict = {"type": "scene", "integrator": {"type": "path", "max_depth": 2}}
    points = []
    for i, ((du, dv), z) in enumerate(zip(targets, depths, strict=True)):
        p_cam = np.array([du / camera.fx * z, dv / camera.fy * z, z])
        p = R @ p_cam + t
        points.append(p)
        radius = 2.0 / camera.fx * z  # two pixels
        M = np.eye(4)
        M[:3, :3] = R @ np.diag([radius, radius, -radius])  # facing the camera (-z of it)
        M[:3, 3] = p
        scene[f"m{i}"] = {
            "type": "disk",
            "to_world": mi.ScalarTransform4f(M),
            "emitter": {"type": "area", "radiance": 1.0},
        }
    image = render(mi, scene, camera, T, 512)[..., 0]
    for p in points:
        q = camera.K @ (R.T @ (p - t))
        u, v = q[0] / q[2], q[1] / q[2]
        r0, c0 = int(round(v)), int(round(u))
        win = image[r0 - 5 : r0 + 6, c0 - 5 : c0 + 6]
        rows, cols = np.mgrid[r0 - 5 : r0 + 6, c0 - 5 : c0 + 6]
        assert win.sum() > 5.0  # the marker is there
        cu, cv = (win * cols).sum() / win.sum(), (win * rows).sum() / win.sum()
        assert abs(cu - u) < 0.1 and abs(cv - v) < 0.1, (cu, u, cv, v)


def test_non_square_pixels_are_refused(mi):  # noqa: ANN001
    with pytest.raises(ConfigError, match="square pixels"):
        load_sensor(mi, CameraModel(80, 60, 70.0, 72.0, 40.0, 30.0), np.eye(4), 4)


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """A unit icosphere (vertices, faces), each subdivision splitting every triangle in four."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]  # fmt: skip
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]  # fmt: skip
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        middle: dict[tuple[int, int], int] = {}

        def mid(i: int, j: int, middle: dict[tuple[int, int], int] = middle) -> int:
            key = (min(i, j), max(i, j))
            if key not in middle:
                m = verts[i] + verts[j]
                verts.append(m / np.linalg.norm(m))
                middle[key] = len(verts) - 1
            return middle[key]

        faces = [
            tri
            for (i, j, k) in faces
            for tri in (
                (i, mid(i, j), mid(k, i)),
                (j, mid(j, k), mid(i, j)),
                (k, mid(k, i), mid(j, k)),
                (mid(i, j), mid(j, k), mid(k, i)),
            )
        ]
    return np.array(verts), np.array(faces)


def sphere_radiance(mi, albedo: float, light: Light, max_depth: int, spp: int) -> tuple[float, float]:  # noqa: ANN001
    """(mean radiance seen inside a closed sphere of Lambertian walls lit by ``light`` as the
    renderer converts it, the sphere's area)."""
    V, F = icosphere(4)
    props = mi.Properties()
    diffuse = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [albedo] * 3}}
    props["bsdf"] = mi.load_dict({"type": "twosided", "bsdf": diffuse})
    walls = mi.Mesh("sphere", len(V), len(F), props=props)
    params = mi.traverse(walls)
    params["vertex_positions"] = mi.Float(V.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(F.astype(np.uint32).ravel())
    params.update()
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth},
        "walls": walls,
        "lamp": light_dict(light, mi.ScalarTransform4f),
    }
    camera = CameraModel(32, 24, 40.0, 40.0, 15.5, 11.5)
    T = look_at(np.array([0.0, 0.3, -0.2]), np.array([0.0, 0.2, -1.0]))
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum()
    return float(render(mi, scene, camera, T, spp).mean()), float(area)


def test_integrating_sphere_reaches_its_closed_form(mi):  # noqa: ANN001
    """Inside a closed sphere of Lambertian walls (albedo a, area A), the light bounced off the
    walls is the same everywhere: irradiance a Phi / (A (1 - a)). A wall the lamp does not light
    directly (the lamp faces up; the camera looks down) then shows radiance a E / pi. An area
    light of raycast intensity I is a Lambertian disc of axial intensity pi I, so of power
    Phi = pi^2 I: the wall's radiance is pi a^2 I / (A (1 - a)). Path tracing reaches it within a
    few percent; direct light alone (max_depth 2) leaves that wall black."""
    a, intensity = 0.8, 2.0
    light = Light(
        "lamp", "area", np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), (1.0, 1.0, 1.0), intensity, 0.05
    )
    value, area = sphere_radiance(mi, a, light, max_depth=100, spp=256)
    expected = np.pi * a * a * intensity / (area * (1.0 - a))
    assert abs(value / expected - 1.0) < 0.04, (value, expected)
    assert sphere_radiance(mi, a, light, max_depth=2, spp=16)[0] < 0.01 * expected


def test_area_light_radiance_keeps_raycast_units(mi):  # noqa: ANN001
    """An area light of intensity I and radius r has radiance I / r^2: its power pi I is what a
    Lambertian disc of axial intensity pi I emits (raycast's I, times pi for radiance = a E / pi)."""
    light = Light("l", "area", np.zeros(3), np.array([0.0, 0.0, -1.0]), (1.0, 0.5, 0.25), 3.0, 0.2)
    d = light_dict(light, mi.ScalarTransform4f)
    assert np.allclose(d["emitter"]["radiance"]["value"], np.array([1.0, 0.5, 0.25]) * 3.0 / 0.04)
    M = np.array(d["to_world"].matrix)
    assert np.allclose(M[:3, 2] / np.linalg.norm(M[:3, 2]), [0.0, 0.0, -1.0])  # faces its direction
    assert np.allclose(np.linalg.norm(M[:3, :3], axis=0), 0.2)


_IDENTITY = np.eye(3)  # a default that is read, never written


def _quad_radiance(
    mi, material, layout: str = "usual", light=(0.0, 0.6, 0.8), eye=(0.3, -0.4, 0.866), R=_IDENTITY, colours=None
) -> np.ndarray:  # noqa: ANN001
    """Mean RGB radiance at the middle of a quad (z = 0, normal +z) of ``material`` under a
    distant light from ``light``, seen from afar from ``eye``, both turned by ``R``. The UVs
    are laid out as glTF's usually are (``usual``: u along +x, v growing toward -y, down the
    image) or ``mirrored`` (u along -x); ``colours``: the corners' vertex colours (one for all,
    or one each)."""
    from agrisim.plugins.render.mitsuba.options import MitsubaOptions
    from agrisim.plugins.render.mitsuba.scene import build
    from agrisim.scene.model import Mesh

    V = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    u = (V[:, 0] + 1.0) / 2.0 if layout == "usual" else (1.0 - V[:, 0]) / 2.0
    uv = np.column_stack([u, (1.0 - V[:, 1]) / 2.0])
    quad = Mesh("quad", V, np.array([[0, 1, 2], [0, 2, 3]]), [material], np.zeros(2, np.int32), uvs=uv)
    if colours is not None:
        quad = dataclasses.replace(quad, colors=np.broadcast_to(colours, (4, 3)))
    scene = build(mi, [quad], [], {}, MitsubaOptions(), {"type": "path", "max_depth": 2}).scene
    to_light = R @ np.asarray(light) / np.linalg.norm(light)
    scene["sun"] = {"type": "directional", "direction": (-to_light).tolist(), "irradiance": 1.0}
    origin = R @ np.asarray(eye) / np.linalg.norm(eye) * 50.0
    up = R @ np.array([0.0, 1.0, 0.0])
    sensor = mi.load_dict(
        {
            "type": "perspective",
            "fov": 1.0,
            "to_world": mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=[0, 0, 0], up=up.tolist()),
            "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": 4},
        }
    )
    image = np.asarray(mi.render(mi.load_dict(scene), sensor=sensor, seed=1), np.float64)[..., :3]
    return image[6:10, 6:10].reshape(-1, 3).mean(axis=0)


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation taking unit vector ``a`` to unit vector ``b`` (Rodrigues)."""
    v, c = np.cross(a, b), float(np.dot(a, b))
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


@pytest.mark.parametrize("layout", ["usual", "mirrored"])
@pytest.mark.parametrize("axis", ["x", "y"])
def test_normal_map_follows_gltf_tangent_frame(mi, layout, axis):  # noqa: ANN001
    """A normal map tilting the normal by 30 degrees along the tangent (x: the direction u
    grows) or the bitangent (y: up in the image, glTF's convention) shades as a plain quad
    whose light and camera are turned the other way by that rotation (only directions
    relative to the normal matter to an isotropic BSDF), on faces with usual and with
    mirrored UVs. The truth is glTF's frame: tangent = dp/du, bitangent = -dp/dv."""
    s, c = math.sin(math.radians(30.0)), math.cos(math.radians(30.0))
    tilt = np.array([s, 0.0, c]) if axis == "x" else np.array([0.0, s, c])
    decoded = np.round((tilt + 1.0) / 2.0 * 255.0) / 255.0 * 2.0 - 1.0
    decoded /= np.linalg.norm(decoded)
    tangent = np.array([1.0, 0.0, 0.0]) if layout == "usual" else np.array([-1.0, 0.0, 0.0])
    bitangent = np.array([0.0, 1.0, 0.0])  # -dp/dv: v grows toward -y in both layouts
    world = decoded[0] * tangent + decoded[1] * bitangent + decoded[2] * np.array([0.0, 0.0, 1.0])
    normal_map = np.broadcast_to(np.round((tilt + 1.0) / 2.0 * 255.0).astype(np.uint8), (4, 4, 3)).copy()
    grey = Material("grey", color=(0.5, 0.5, 0.5, 1.0), roughness=0.5)
    mapped = _quad_radiance(mi, dataclasses.replace(grey, normal_map=normal_map), layout)
    reference = _quad_radiance(mi, grey, layout, R=_rotation_between(world, np.array([0.0, 0.0, 1.0])))
    flat = _quad_radiance(mi, grey, layout)
    assert np.allclose(mapped, reference, rtol=0.01), (mapped, reference, flat)
    assert abs(mapped[0] / flat[0] - 1.0) > 0.05  # the map does something


def test_the_back_of_a_two_sided_surface_has_its_own_colour_and_roughness(mi):  # noqa: ANN001
    """A leaf's lower side (``back_color``, ``back_roughness``): seen and lit from below, the
    quad shades as a plain one of the back's colour and roughness seen and lit from above at
    the same angles; from above, as the plain front."""
    leaf = Material("leaf", color=(0.4, 0.5, 0.2, 1.0), roughness=0.3, back_color=(1.5, 1.2, 2.0), back_roughness=0.9)
    plain = dataclasses.replace(leaf, back_color=None, back_roughness=None)
    as_back = dataclasses.replace(plain, color=(0.6, 0.6, 0.4, 1.0), roughness=0.9)
    below, seen_below = (0.0, -0.6, -0.8), (0.3, -0.4, -0.866)
    above, seen_above = (0.0, -0.6, 0.8), (0.3, -0.4, 0.866)
    back = _quad_radiance(mi, leaf, light=below, eye=seen_below)
    assert np.allclose(back, _quad_radiance(mi, as_back, light=above, eye=seen_above), rtol=0.01)
    assert np.allclose(_quad_radiance(mi, leaf), _quad_radiance(mi, plain), rtol=1e-6)
    assert not np.allclose(back, _quad_radiance(mi, plain, light=below, eye=seen_below), rtol=0.05)


def test_metallic_roughness_texture_scales_the_factors(mi):  # noqa: ANN001
    """A metallic-roughness texture (green: roughness, blue: metallic, linear) times factors
    shades as the product given as plain factors; and differently from the factors alone."""
    texture = np.zeros((4, 4, 3), np.uint8)
    texture[..., 1], texture[..., 2] = 102, 204  # 0.4, 0.8
    base = Material("m", color=(0.8, 0.5, 0.3, 1.0), roughness=0.5, metallic=0.5)
    textured = _quad_radiance(
        mi, dataclasses.replace(base, metallic_roughness=texture), light=(0.2, 0.1, 0.9), eye=(-0.2, -0.1, 0.9)
    )
    plain = _quad_radiance(
        mi, dataclasses.replace(base, roughness=0.2, metallic=0.4), light=(0.2, 0.1, 0.9), eye=(-0.2, -0.1, 0.9)
    )
    factors = _quad_radiance(mi, base, light=(0.2, 0.1, 0.9), eye=(-0.2, -0.1, 0.9))
    assert np.allclose(textured, plain, rtol=0.01), (textured, plain)
    assert not np.allclose(textured, factors, rtol=0.05)


def test_transmission_texture_is_the_transmitted_colour(mi):  # noqa: ANN001
    """Seen from the dark side of a back-lit card, a transmission texture (glTF's colour of
    diffuse transmission) glows as much as agrisim's transmittance per unit of albedo giving
    the same colour; an opaque card does not."""
    from agrisim.scene.colour import srgb_to_linear

    texel = np.array([120, 200, 60], np.uint8)
    through = srgb_to_linear(texel / 255.0)
    leaf = Material("leaf", color=(0.2, 0.3, 0.1, 1.0), roughness=0.4)
    textured = dataclasses.replace(leaf, transmission=np.broadcast_to(texel, (2, 2, 3)).copy())
    per_albedo = dataclasses.replace(leaf, transmittance=tuple(through / np.array([0.2, 0.3, 0.1])))
    below = (0.3, 0.2, -0.9)
    a, b = _quad_radiance(mi, textured, light=below), _quad_radiance(mi, per_albedo, light=below)
    assert np.allclose(a, b, rtol=0.01), (a, b)
    assert np.all(_quad_radiance(mi, leaf, light=below) < 0.01 * a)


def test_a_vertex_colour_multiplies_both_sides_and_the_light_through(mi):  # noqa: ANN001
    """glTF's COLOR_0 multiplies what the colour factor multiplies: a textured translucent leaf
    with its own back, vertex colours c on every corner, shades as the same leaf with colour
    factor c lit and seen from above, lit from below and seen from above (the light through),
    and lit and seen from below (the back); the colours stay below the translucency's caps."""
    tint = (0.9, 0.55, 0.3)
    texture = np.zeros((8, 8, 4), np.uint8)
    texture[..., :3] = np.arange(64, dtype=np.uint8).reshape(8, 8, 1) + 60
    texture[..., 3] = 255
    leaf = Material(
        "leaf",
        color=(1.0, 1.0, 1.0, 1.0),
        albedo=texture,
        transmittance=(0.5, 1.0, 0.2),
        roughness=0.4,
        back_color=(1.3, 1.2, 1.3),
        back_roughness=0.8,
    )
    factor = dataclasses.replace(leaf, color=(*tint, 1.0))
    above, below = (0.0, -0.6, 0.8), (0.3, 0.2, -0.9)
    seen_above, seen_below = (0.3, -0.4, 0.866), (0.3, -0.4, -0.866)
    for light, eye in ((above, seen_above), (below, seen_above), (below, seen_below)):
        vertex = _quad_radiance(mi, leaf, light=light, eye=eye, colours=tint)
        expected = _quad_radiance(mi, factor, light=light, eye=eye)
        assert expected.min() > 1e-4  # lit on the side seen
        np.testing.assert_allclose(vertex, expected, rtol=1e-4)
        assert not np.allclose(vertex, _quad_radiance(mi, leaf, light=light, eye=eye), rtol=0.05)
    # Colours that vary over the faces are interpolated: running linearly in x from c - d to
    # c + d, their mean over the quad's middle (symmetric about it) is c's.
    d = np.array([0.08, 0.1, -0.1])
    ramp = np.where(np.array([[-1.0], [1.0], [1.0], [-1.0]]) > 0, np.add(tint, d), np.subtract(tint, d))
    np.testing.assert_allclose(_quad_radiance(mi, leaf, colours=ramp), _quad_radiance(mi, factor), rtol=2e-3)


def test_the_vertex_tints_colour_is_mitsubas_own_interpolation_bit_for_bit(mi):  # noqa: ANN001
    """The tint reads its colours from :class:`VertexColours` (gathers, not a call on the shape
    inside the BSDF's call: a kernel half the size), with Mitsuba's arithmetic copied: at random
    hits on two meshes of random triangles and colours it is ``eval_attribute_3`` of the same
    colours bit for bit. A Mitsuba whose interpolation changed fails here, not in the images."""
    import drjit as dr

    from agrisim.plugins.render.mitsuba.vertex_tint import VertexColours

    rng = np.random.default_rng(7)
    store, shapes = VertexColours(), []
    for k in range(2):
        n = 40
        v = rng.uniform(-1.0, 1.0, (3 * n, 3)).astype(np.float32)
        v[:, 2] = v[:, 2] * 0.2 + k  # two slabs of triangles, one above the other
        f = np.arange(3 * n, dtype=np.uint32).reshape(n, 3)
        colours = rng.uniform(0.0, 1.0, (3 * n, 3)).astype(np.float32)
        shape = mi.Mesh(f"m{k}", len(v), len(f))
        params = mi.traverse(shape)
        params["vertex_positions"] = mi.Float(v.ravel())
        params["faces"] = mi.UInt32(f.ravel())
        params.update()
        shape.add_attribute("vertex_color", 3, mi.Float(colours.ravel()))
        store.add(mi, shape, v, f, colours)
        shapes.append(shape)
    store.finish(mi)
    scene = mi.load_dict({"type": "scene", "a": shapes[0], "b": shapes[1]})
    m = 20_000
    origins = np.column_stack([rng.uniform(-1, 1, m), rng.uniform(-1, 1, m), np.full(m, 3.0)])
    targets = np.column_stack([rng.uniform(-1, 1, m), rng.uniform(-1, 1, m), rng.uniform(-0.2, 1.2, m)])
    d = targets - origins
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rays = mi.Ray3f(mi.Point3f(*(origins.T.astype(np.float32))), mi.Vector3f(*(d.T.astype(np.float32))))
    si = scene.ray_intersect(rays)
    hit = si.is_valid()
    ours = np.asarray(store.eval(mi, si, hit))
    theirs = np.asarray(si.shape.eval_attribute_3("vertex_color", si, hit))
    hits = np.asarray(hit)
    shape_ids = np.asarray(dr.reinterpret_array(mi.UInt32, si.shape))  # the value si.shape holds
    assert hits.mean() > 0.3 and len(set(shape_ids[hits].tolist())) == 2  # both meshes hit, often
    assert np.array_equal(ours.view(np.uint32), theirs.view(np.uint32))
