"""The ``raycast`` renderer: exact depth, pixel-centre intrinsics, alpha-tested continuation,
texture labels (texture and repopa modes, organs), shadows through cut-out cards, the arms.

Scenes are built here from the data model (planes, spheres, textured cards), so every expected
value is analytic or recomputed independently with Open3D and :mod:`agrisim.scene.texturing`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import open3d as o3d
import pytest

from agrisim.config import RenderConfig
from agrisim.interfaces import CameraModel
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.materials import SRGB_TO_LINEAR, MaterialTable
from agrisim.plugins.render.raycast.renderer import RaycastRenderer
from agrisim.scene import texturing
from agrisim.scene.camera import from_fov
from agrisim.scene.colour import encode_srgb8, srgb_to_linear
from agrisim.scene.model import Label, LabelTable, Light, Material, Mesh, Scene

CAMERA = from_fov(60.0, 160, 120)


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """world_T_camera of an OpenCV camera at ``eye`` looking at ``target``."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(z, (0.0, 1.0, 0.0))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


def quad(name: str, corners, material: Material) -> Mesh:
    """A rectangle of two triangles, UVs (0, 0) at corner 0, (1, 0) at corner 1, (1, 1) at corner 2
    (glTF: u right, v down in the image)."""
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return Mesh(name, np.array(corners, float), faces, [material], np.zeros(2, np.int32), uvs)


def sphere(name: str, center, radius: float, material: Material, subdivisions: int = 4) -> Mesh:
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return Mesh(name, m.vertices + np.asarray(center), m.faces, [material], np.zeros(len(m.faces), np.int32))


def renderer(scene: Scene, cell, options: RaycastOptions | None = None, **settings) -> RaycastRenderer:
    """A raycast renderer; ``settings`` are RenderConfig's fields or RaycastOptions' (these
    override ``options``)."""
    settings.setdefault("hide_robots", True)
    own = {k: settings.pop(k) for k in list(settings) if k in RaycastOptions.model_fields}
    options = (options or RaycastOptions()).model_copy(update=own)
    return RaycastRenderer(scene, cell, RenderConfig(**settings), options)


def pixel_rays(camera: CameraModel, world_T_camera: np.ndarray) -> np.ndarray:
    """H x W x 6 rays through pixel centres (integer coordinates), direction z = 1 in the camera."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    d = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], -1)
    dw = d @ world_T_camera[:3, :3].T
    o = np.broadcast_to(world_T_camera[:3, 3], dw.shape)
    return np.concatenate([o, dw], -1)


def back_project(depth: np.ndarray, camera: CameraModel, world_T_camera: np.ndarray) -> np.ndarray:
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    p = np.stack([(u - camera.cx) / camera.fx * depth, (v - camera.cy) / camera.fy * depth, depth], -1)
    return p @ world_T_camera[:3, :3].T + world_T_camera[:3, 3]


GREY = Material("grey", color=(0.5, 0.5, 0.5, 1.0))
LIGHTS = [Light("key", "area", np.array([0.0, 0.0, 4.0]), np.array([0.0, 0.0, -1.0]), intensity=16.0, radius=0.2)]


# ------------------------------------------------------------------------------ core checks


def test_mitsuba_barycentrics_match_interpolate_uv():
    """Mitsuba's prim_uv (Embree's and OptiX's u, v) is point = (1-u-v) A + u B + v C, the
    convention agrisim.scene.texturing.interpolate_uv and the exact pass assume; Open3D's Embree
    says the same."""
    from agrisim.plugins.render.mitsuba.variant import use_variant

    mi = use_variant("auto")
    rng = np.random.default_rng(1)
    tri = rng.uniform(-1, 1, (3, 3)) + [0, 0, 3]
    mesh = Mesh("t", tri, np.array([[0, 1, 2]]), [GREY], np.zeros(1, np.int32), rng.random((3, 2)).astype(np.float32))
    shape = mi.Mesh("t", 3, 1, has_vertex_normals=False, has_vertex_texcoords=False)
    params = mi.traverse(shape)
    params["vertex_positions"] = mi.Float(tri.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(np.array([0, 1, 2], np.uint32))
    params.update()
    scene = mi.load_dict({"type": "scene", "t": shape})
    w = np.array([[0.2, 0.3], [0.6, 0.1], [0.05, 0.9]])
    points = ((1 - w[:, :1] - w[:, 1:]) * tri[0] + w[:, :1] * tri[1] + w[:, 1:] * tri[2]).astype(np.float32)
    ray = mi.Ray3f(mi.Point3f(0.0), mi.Vector3f(points[:, 0], points[:, 1], points[:, 2]))
    bary = np.asarray(scene.ray_intersect_preliminary(ray).prim_uv).T
    np.testing.assert_allclose(bary, w, atol=1e-5)
    o3 = o3d.t.geometry.RaycastingScene()
    o3.add_triangles(o3d.core.Tensor(tri.astype(np.float32)), o3d.core.Tensor(np.array([[0, 1, 2]], np.uint32)))
    rays = np.concatenate([np.zeros((3, 3)), points], 1).astype(np.float32)
    np.testing.assert_allclose(o3.cast_rays(o3d.core.Tensor(rays))["primitive_uvs"].numpy(), w, atol=1e-5)
    expected = (1 - w[:, :1] - w[:, 1:]) * mesh.uvs[0] + w[:, :1] * mesh.uvs[1] + w[:, 1:] * mesh.uvs[2]
    np.testing.assert_allclose(texturing.interpolate_uv(mesh, np.zeros(3, int), bary), expected, atol=1e-5)


def test_registered_with_options_model():
    from pydantic import ValidationError

    from agrisim.plugins.render import raycast

    (spec,) = raycast.agrisim_renderers()
    assert spec.name == "raycast" and spec.options_model is RaycastOptions
    with pytest.raises(ValidationError):
        RaycastOptions(shininess=3)
    assert all(f.description for f in RaycastOptions.model_fields.values())


# ------------------------------------------------------------------------------ geometry


def test_depth_is_exact_planar_z(cell):
    floor = quad("floor", [[-40, -40, 0], [40, -40, 0], [40, 40, 0], [-40, 40, 0]], GREY)
    center, radius = np.array([0.1, -0.05, 0.25]), 0.25
    ball = sphere("ball", center, radius, GREY)
    T = look_at([1.2, -0.9, 1.1], [0.0, 0.0, 0.1])
    frame = renderer(Scene([floor, ball], LIGHTS, LabelTable()), cell, shadow_samples=0).render(CAMERA, T, {})
    assert frame.depth.dtype == np.float32 and frame.depth.shape == (120, 160)
    assert (frame.depth > 0).all()

    rays = pixel_rays(CAMERA, T)
    t_floor = -rays[..., 2] / rays[..., 5]  # direction has unit camera z: t is planar depth
    points = back_project(frame.depth.astype(float), CAMERA, T)
    dist = np.linalg.norm(points - center, axis=-1)
    on_ball = dist < radius + 1e-3
    assert 0.03 < on_ball.mean() < 0.9
    # Floor pixels: depth equals the analytic planar z, back-projected points lie on z = 0.
    np.testing.assert_allclose(frame.depth[~on_ball], t_floor[~on_ball], atol=2e-5, rtol=0)
    assert np.abs(points[~on_ball][:, 2]).max() < 2e-5
    # Sphere pixels lie on the tessellated sphere (within its sagitta) and in front of the floor.
    sagitta = radius * (1 - np.cos(np.radians(64 / 2**4) / 2)) * 2
    assert (dist[on_ball] <= radius + 2e-5).all() and (dist[on_ball] >= radius - sagitta).all()
    assert (frame.depth[on_ball] < t_floor[on_ball]).all()


def test_pixel_centres_at_integer_coordinates(cell):
    """A tiny card centred on a point that K projects to (u, v) + (0.03, -0.04) px is seen by
    pixel (u, v) only: pixel centres are at integer coordinates (no half-pixel shift)."""
    camera = CameraModel(160, 120, 150.0, 140.0, 77.3, 61.8)  # off-centre principal point
    T = look_at([0.3, -1.5, 0.8], [0.0, 0.0, 0.5])
    rng = np.random.default_rng(3)
    targets = [(20, 30), (80, 60), (150, 10), (5, 110), (77, 62)]
    meshes, expected = [], []
    for k, (u, v) in enumerate(targets):
        z = rng.uniform(0.8, 2.0)
        uc, vc = u + 0.03, v - 0.04
        p_cam = np.array([(uc - camera.cx) / camera.fx * z, (vc - camera.cy) / camera.fy * z, z])
        half = 0.15 * z / camera.fx  # 0.15 px
        corners = [p_cam + [sx * half, sy * half, 0.0] for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        world = [T[:3, :3] @ c + T[:3, 3] for c in corners]
        meshes.append(quad(f"dot{k}", world, GREY))
        expected.append((v, u, z))
    frame = renderer(Scene(meshes, LIGHTS, LabelTable()), cell, shadow_samples=0).render(camera, T, {})
    assert (frame.depth > 0).sum() == len(targets)
    for v, u, z in expected:
        assert frame.depth[v, u] == pytest.approx(z, abs=1e-5)
        # The projection with K of the back-projected pixel is the pixel itself.
        p = np.array([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0]) * frame.depth[v, u]
        uvw = camera.K @ p
        np.testing.assert_allclose(uvw[:2] / uvw[2], [u, v], atol=1e-9)


# ------------------------------------------------------------------------------ opacity and labels


def card_texture(size: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Albedo: green, its left half (u < 0.5) transparent, plus a square hole in the right half;
    alpha straddles the 0.5 cutoff (127 cut, 128 kept)."""
    albedo = np.zeros((size, size, 4), np.uint8)
    albedo[..., 1] = 200
    albedo[..., 3] = 128
    albedo[:, : size // 2, 3] = 127
    albedo[size // 4 : size // 2, 5 * size // 8 : 6 * size // 8, 3] = 0  # a hole
    labels = np.zeros((size, size), np.uint8)
    labels[: size // 2] = 3  # top half (v < 0.5): organ 3
    labels[size // 2 :] = 5  # bottom half: organ 5
    labels[:, : size // 4] = 0  # part of the transparent half has no label at all
    return albedo, labels


def card_scene(with_labels: bool = True) -> Scene:
    albedo, labels = card_texture()
    leaf = Material("leaf", albedo=albedo, labels=labels if with_labels else None, label=2, alpha_mode="MASK")
    # Card in the plane y = 0 facing -y; UV (0,0) top-left seen from the camera at -y.
    card = quad("plant", [[-0.3, 0, 0.8], [0.3, 0, 0.8], [0.3, 0, 0.2], [-0.3, 0, 0.2]], leaf)
    wall = quad("wall", [[-3, 1, -2], [3, 1, -2], [3, 1, 3], [-3, 1, 3]], Material("wall", color=(0.8, 0.1, 0.1, 1.0)))
    table = LabelTable(
        [Label(0, "background", (0, 0, 0)), Label(3, "leaf", (0, 255, 0)), Label(5, "vein", (80, 0, 80))]
    )
    return Scene([card, wall], LIGHTS, table)


# Slightly off-axis, so that no pixel ray meets a texel boundary exactly (a tie could go either
# way between two casts of rays rounded differently).
CARD_T = look_at([0.0123, -1.2, 0.5077], [0.0123, 0.0, 0.5077])


def card_region():
    """Pixel masks of the card's left (transparent) and right (opaque) halves, from its corners."""
    K, camera_T_world = CAMERA.K, np.linalg.inv(CARD_T)

    def px(p):
        q = K @ (camera_T_world[:3, :3] @ p + camera_T_world[:3, 3])
        return q[:2] / q[2]

    (u0, v0), (u1, v1) = px([-0.3, 0, 0.8]), px([0.3, 0, 0.2])
    um = px([0.0, 0, 0.5])[0]
    u, v = np.meshgrid(np.arange(CAMERA.width), np.arange(CAMERA.height))
    inside = (v > v0 + 1) & (v < v1 - 1)
    return inside & (u > u0 + 1) & (u < um - 1), inside & (u > um + 1) & (u < u1 - 1)


def independent_first_hit(scene: Scene, rays: np.ndarray):
    """(mesh index, face, uv) of the first hit of each ray (K x 6), straight from Open3D."""
    rc = o3d.t.geometry.RaycastingScene()
    ids = [
        rc.add_triangles(o3d.core.Tensor(m.vertices.astype(np.float32)), o3d.core.Tensor(m.faces.astype(np.uint32)))
        for m in scene.meshes
    ]
    r = rc.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))
    g, f, b = r["geometry_ids"].numpy(), r["primitive_ids"].numpy().astype(int), r["primitive_uvs"].numpy()
    which = np.array([ids.index(x) if x in ids else -1 for x in g])
    return which, f, b


def test_alpha_tested_continuation_texture_mode(cell):
    scene = card_scene()
    frame = renderer(scene, cell, shadow_samples=0, seg_mode="texture", labels="organs").render(CAMERA, CARD_T, {})
    left, right = card_region()
    wall_z, card_z = 1.2 + 1.0, 1.2
    # Left half is cut away: the wall's depth and colour; right half: the card's.
    np.testing.assert_allclose(frame.depth[left], wall_z, atol=1e-5)
    hole = np.abs(frame.depth - wall_z) < 1e-4
    assert (hole & right).sum() > 20  # the square hole in the opaque half
    np.testing.assert_allclose(frame.depth[right & ~hole], card_z, atol=1e-5)
    assert (frame.rgb[left][:, 0] > frame.rgb[left][:, 1]).all()  # red wall
    assert (frame.rgb[right & ~hole][:, 1] > frame.rgb[right & ~hole][:, 0]).all()  # green leaf
    # Labels: plant only on opaque texels, never on the transparent half or through the hole.
    assert (frame.labels[left] == 0).all() and (frame.labels[hole] == 0).all()
    assert (frame.labels[right & ~hole] > 0).all()

    # Every labelled pixel's first hit, recomputed independently, is the plant on an opaque texel.
    rays = pixel_rays(CAMERA, CARD_T)[frame.labels > 0]
    which, faces, bary = independent_first_hit(scene, rays)
    plant = scene.mesh("plant")
    assert (which == 0).all()
    uv = texturing.interpolate_uv(plant, faces, bary)
    assert texturing.opaque(plant.materials[0], uv).all()
    np.testing.assert_array_equal(texturing.label_at(plant.materials[0], uv), frame.labels[frame.labels > 0])
    # ... and every unlabelled pixel whose first hit is the plant is on a cut-out texel.
    rays = pixel_rays(CAMERA, CARD_T)[frame.labels == 0]
    which, faces, bary = independent_first_hit(scene, rays)
    on = which == 0
    uv = texturing.interpolate_uv(plant, faces[on], bary[on])
    assert not texturing.opaque(plant.materials[0], uv).any()


def test_bilinear_albedo_does_not_bleed_cut_away_texels(cell):
    scene = card_scene()
    card = scene.mesh("plant").materials[0]
    card.albedo[card.albedo[..., 3] < 128, :3] = (255, 0, 255)  # cut-away texels: magenta
    scene.meshes[1].materials[0].color = (0.0, 0.0, 0.0, 1.0)  # black wall
    for texture_filter in ("bilinear", "nearest"):
        options = RaycastOptions(texture_filter=texture_filter)
        frame = renderer(scene, cell, options, shadow_samples=0).render(CAMERA, CARD_T, {})
        card_px = frame.labels > 0
        assert card_px.sum() > 100
        assert (frame.rgb[card_px][:, 0] == 0).all() and (frame.rgb[card_px][:, 2] == 0).all()
        assert (frame.rgb[~card_px] == 0).all()


def test_repopa_labels_whole_card_while_depth_sees_through(cell):
    scene = card_scene()
    texture = renderer(scene, cell, shadow_samples=0, seg_mode="texture").render(CAMERA, CARD_T, {})
    repopa = renderer(scene, cell, shadow_samples=0, seg_mode="repopa").render(CAMERA, CARD_T, {})
    left, right = card_region()
    # Same RGB and depth (alpha-tested), labels differ: repopa covers the whole card.
    np.testing.assert_array_equal(repopa.depth, texture.depth)
    np.testing.assert_array_equal(repopa.rgb, texture.rgb)
    assert (repopa.labels[left | right] == 1).all()
    assert set(np.unique(repopa.labels)) == {0, 1}
    assert (repopa.depth[left] > 2.0).all()  # mask over pixels whose depth is the wall behind
    assert (repopa.labels >= texture.labels).all() and repopa.labels.sum() > 1.8 * texture.labels.sum()
    # Every repopa-labelled pixel's first hit of any opacity is the plant.
    which, _, _ = independent_first_hit(scene, pixel_rays(CAMERA, CARD_T)[repopa.labels > 0])
    assert (which == 0).all()


def test_repopa_organs_fill_unlabelled_cut_out_texels(cell):
    scene = card_scene()
    frame = renderer(scene, cell, shadow_samples=0, seg_mode="repopa", labels="organs").render(CAMERA, CARD_T, {})
    left, right = card_region()
    # Where the label texture is 0 on a cut-out texel, the material's most common organ id.
    assert set(np.unique(frame.labels[left | right])) <= {3, 5}
    assert set(np.unique(frame.labels[left])) == {3, 5}


def test_multi_label_organs_and_plant(cell):
    scene = card_scene()
    organs = renderer(scene, cell, shadow_samples=0, labels="organs").render(CAMERA, CARD_T, {})
    plant = renderer(scene, cell, shadow_samples=0, labels="plant").render(CAMERA, CARD_T, {})
    assert set(np.unique(organs.labels)) == {0, 3, 5}
    assert set(np.unique(plant.labels)) == {0, 1}
    np.testing.assert_array_equal(plant.labels, (organs.labels > 0).astype(np.uint8))
    # Organ 3 is the top half of the texture (v < 0.5): the upper half of the card in the image.
    rows3 = np.nonzero(organs.labels == 3)[0]
    rows5 = np.nonzero(organs.labels == 5)[0]
    assert rows3.max() < rows5.min()
    # Leaf instance ids come with the labels' hits.
    with_ids = card_scene()
    with_ids.meshes[0].face_instance = np.array([7, 7], np.uint16)
    inst = renderer(with_ids, cell, shadow_samples=0, labels="organs").render(CAMERA, CARD_T, {})
    np.testing.assert_array_equal(inst.instances, np.where(organs.labels > 0, 7, 0))
    assert organs.instances is None
    # Without a label texture the material's constant label; only the plant mesh is labelled.
    const = renderer(card_scene(with_labels=False), cell, shadow_samples=0, labels="organs").render(CAMERA, CARD_T, {})
    assert set(np.unique(const.labels)) == {0, 2}


def test_single_sided_back_faces_are_culled(cell):
    one_sided = Material("one", color=(0.2, 0.2, 0.9, 1.0), double_sided=False)
    # Its front (counter-clockwise seen from +y) faces away from the camera at -y.
    card = quad("card", [[-0.3, 0, 0.8], [0.3, 0, 0.8], [0.3, 0, 0.2], [-0.3, 0, 0.2]], one_sided)
    wall = quad("wall", [[-3, 1, -2], [3, 1, -2], [3, 1, 3], [-3, 1, 3]], GREY)
    n = np.cross(card.vertices[1] - card.vertices[0], card.vertices[2] - card.vertices[0])
    assert n[1] > 0
    frame = renderer(Scene([card, wall], LIGHTS, LabelTable()), cell, shadow_samples=0).render(CAMERA, CARD_T, {})
    np.testing.assert_allclose(frame.depth, frame.depth[60, 80], rtol=0.5)  # only the wall
    assert frame.depth[60, 80] == pytest.approx(2.2, abs=1e-5)


def _albedo(mats: MaterialTable, uv: np.ndarray, material: int) -> np.ndarray:
    """Bilinear albedo of ``material`` at ``uv`` (K x 2) through the Dr.Jit lookup."""
    from agrisim.plugins.render.mitsuba.variant import use_variant
    from agrisim.plugins.render.raycast.materials import MaterialArrays

    mi = use_variant("auto")
    arrays = MaterialArrays(mi, mats)
    mat = mi.UInt32(np.full(len(uv), material, np.uint32))
    return np.asarray(arrays.albedo(mi.Vector2f(uv[:, 0], uv[:, 1]), mat, bilinear=True)).T


def test_bilinear_albedo_wraps_like_a_direct_lookup():
    """The packed albedo table (linear, colour factor applied, padded for bilinear lookups)
    gives what a direct bilinear lookup in linear light with wrapped texel indices gives, also
    at the texture's edges and for UVs outside [0, 1); untextured materials give their colour."""
    rng = np.random.default_rng(3)
    texture = rng.integers(0, 256, (5, 7, 4), dtype=np.uint8)
    mats = MaterialTable()
    textured = mats.add(Material("t", color=(0.5, 1.0, 0.25, 1.0), albedo=texture))
    plain = mats.add(Material("plain", color=(0.2, 0.4, 0.6, 1.0)))
    mats.finish()
    uv = rng.uniform(-2.0, 3.0, (2000, 2)).astype(np.float32)
    uv[:4] = [[0.0, 0.0], [1.0, 1.0], [0.999, 0.5], [-0.001, 0.2]]
    linear = SRGB_TO_LINEAR[texture[..., :3]].astype(np.float64) * (0.5, 1.0, 0.25)
    f = uv.astype(np.float64) * (7, 5) - 0.5
    x0, y0 = np.floor(f).astype(int).T
    ax, ay = (f - np.floor(f)).T[..., None]
    x1, y1, x0, y0 = (x0 + 1) % 7, (y0 + 1) % 5, x0 % 7, y0 % 5
    expected = (linear[y0, x0] * (1 - ax) + linear[y0, x1] * ax) * (1 - ay) + (
        linear[y1, x0] * (1 - ax) + linear[y1, x1] * ax
    ) * ay
    np.testing.assert_allclose(_albedo(mats, uv, textured), expected, atol=2e-6)
    got = _albedo(mats, uv, plain)
    np.testing.assert_array_equal(got, np.broadcast_to(np.float32([0.2, 0.4, 0.6]), got.shape))


# ------------------------------------------------------------------------------ shading


def test_vertex_colours_multiply_the_albedo_interpolated_over_each_face(cell):
    """glTF's COLOR_0 (``Mesh.colors``): a grey card whose left corners are white and right
    corners (0.3, 0.6, 1) shows, in linear light, the plain card's colour times a colour that
    runs linearly across it in x (the camera faces the card: barycentrics are linear in x)."""
    right = np.array([0.3, 0.6, 1.0])
    frames = []
    for tint in (False, True):
        scene = card_scene()
        card = scene.mesh("plant")
        card.materials[0].albedo[..., :3] = 150
        if tint:
            colours = np.where(card.vertices[:, :1] > 0, right, 1.0)
            scene.meshes[0] = dataclasses.replace(card, colors=colours)
        frames.append(renderer(scene, cell, shadow_samples=0).render(CAMERA, CARD_T, {}))
    plain, tinted = frames
    on = (plain.labels > 0) & (tinted.labels > 0)
    assert on.sum() > 300 and plain.rgb[on].max() < 250  # not clipped
    x = back_project(tinted.depth.astype(float), CAMERA, CARD_T)[on][:, 0]
    expected = 1.0 + (right - 1.0) * ((x[:, None] + 0.3) / 0.6)
    ratio = srgb_to_linear(tinted.rgb[on] / 255.0) / srgb_to_linear(plain.rgb[on] / 255.0)
    np.testing.assert_allclose(ratio, expected, atol=0.02)
    np.testing.assert_array_equal(tinted.labels, plain.labels)  # colour changes nothing else
    np.testing.assert_array_equal(tinted.depth, plain.depth)


def shadow_scene(cut: bool) -> Scene:
    floor = quad("floor", [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], Material("floor", color=(0.7, 0.7, 0.7, 1)))
    albedo = np.full((8, 8, 4), 255, np.uint8)
    if cut:
        albedo[::2, ::2, 3] = 0  # a grid of holes: a quarter of the card is cut away
        albedo[1::2, 1::2, 3] = 0  # ... half of it
    card = quad(
        "plant",
        [[-0.25, -0.25, 0.5], [0.25, -0.25, 0.5], [0.25, 0.25, 0.5], [-0.25, 0.25, 0.5]],
        Material("card", albedo=albedo, alpha_mode="MASK", label=1),
    )
    light = Light("top", "area", np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, -1.0]), intensity=4.0, radius=0.05)
    return Scene([floor, card], [light], LabelTable())


SHADOW_T = look_at([1.4, 0.0, 1.0], [0.0, 0.0, 0.0])


def floor_brightness(frame, scene):
    """Mean green of floor pixels under the card (|x|, |y| < 0.15) and far from it (0.6 < |p| < 1)."""
    p = back_project(frame.depth.astype(float), CAMERA, SHADOW_T)
    floor = (np.abs(p[..., 2]) < 1e-4) & (frame.depth > 0)
    r = np.linalg.norm(p[..., :2], axis=-1)
    under = floor & (np.abs(p[..., 0]) < 0.15) & (np.abs(p[..., 1]) < 0.15)
    ring = floor & (r > 0.5) & (r < 0.7)
    assert under.sum() > 30 and ring.sum() > 30
    g = frame.rgb[..., 1].astype(float)
    return g[under].mean(), g[ring].mean()


def test_shadows_holes_and_no_shadow_mode(cell):
    solid, cut = shadow_scene(False), shadow_scene(True)
    under, ring = floor_brightness(renderer(solid, cell, shadow_samples=4).render(CAMERA, SHADOW_T, {}), solid)
    assert under < 0.5 * ring  # the card's shadow (ambient only)
    under_cut, ring_cut = floor_brightness(renderer(cut, cell, shadow_samples=4).render(CAMERA, SHADOW_T, {}), cut)
    assert under + 15 < under_cut < ring_cut  # light through the holes
    under0, ring0 = floor_brightness(renderer(solid, cell, shadow_samples=0).render(CAMERA, SHADOW_T, {}), solid)
    assert under0 > ring0  # hard-lit, no shadow: right below the light is the brightest


def test_same_inputs_give_identical_images(cell):
    scene = shadow_scene(True)
    a = renderer(scene, cell, shadow_samples=3).render(CAMERA, SHADOW_T, {})
    c = renderer(scene, cell, shadow_samples=3).render(CAMERA, SHADOW_T, {})
    assert a.rgb.tobytes() == c.rgb.tobytes()
    # Batches do not change the result (each pixel has its own random stream).
    batched = renderer(scene, cell, RaycastOptions(batch_pixels=2048), shadow_samples=3).render(CAMERA, SHADOW_T, {})
    assert batched.rgb.tobytes() == a.rgb.tobytes()
    d = renderer(scene, cell, RaycastOptions(seed=7), shadow_samples=3).render(CAMERA, SHADOW_T, {})
    assert a.rgb.tobytes() != d.rgb.tobytes()  # another seed: other noise in the penumbra
    np.testing.assert_array_equal(a.depth, d.depth)


def test_the_kept_radiance_encodes_to_the_rgb(cell):
    """``radiance`` keeps what the RGB was encoded from: through the one encoder every renderer
    shares, at the run's exposure, it gives the RGB again (a background of its own included),
    and keeping it changes nothing else."""
    scene = shadow_scene(True)
    options = RaycastOptions(radiance=True, exposure=1.7, background=(30, 60, 90), batch_pixels=2048)
    kept = renderer(scene, cell, options, shadow_samples=3).render(CAMERA, SHADOW_T, {})
    plain = renderer(scene, cell, options.model_copy(update={"radiance": False}), shadow_samples=3)
    plain_frame = plain.render(CAMERA, SHADOW_T, {})
    assert plain_frame.radiance is None and kept.radiance is not None
    assert kept.radiance.shape == (*kept.rgb.shape[:2], 3) and kept.radiance.dtype == np.float32
    encoded = np.empty((kept.rgb.size // 3, 3), np.uint8)
    encode_srgb8(kept.radiance.reshape(-1, 3).copy(), encoded, exposure=1.7)
    np.testing.assert_array_equal(encoded.reshape(kept.rgb.shape), kept.rgb)
    assert (kept.depth == 0).any()  # the background is in the test
    np.testing.assert_array_equal(kept.rgb, plain_frame.rgb)
    np.testing.assert_array_equal(kept.labels, plain_frame.labels)


def test_adaptive_shadow_sampling_matches_full_sampling(cell):
    scene = shadow_scene(True)
    side = Light("side", "spot", np.array([1.0, 1.0, 1.0]), -np.ones(3) / np.sqrt(3), intensity=2.0, cone_deg=60)
    scene.lights.append(side)

    def render(**options):
        return renderer(scene, cell, RaycastOptions(**options), shadow_samples=16).render(CAMERA, SHADOW_T, {})

    full, other, fast = render(adaptive_after=0), render(adaptive_after=0, seed=9), render(adaptive_after=4)
    noise = np.abs(full.rgb.astype(float) - other.rgb).mean()
    assert np.abs(full.rgb.astype(float) - fast.rgb).mean() < 1.5 * noise + 0.2
    assert abs(full.rgb.astype(float).mean() - fast.rgb.mean()) < 0.5


def test_supersampling_keeps_labels_and_depth_exact(cell):
    scene = card_scene()
    one = renderer(scene, cell, shadow_samples=0).render(CAMERA, CARD_T, {})
    four = renderer(scene, cell, shadow_samples=0, supersample=3).render(CAMERA, CARD_T, {})
    np.testing.assert_array_equal(one.labels, four.labels)
    np.testing.assert_array_equal(one.depth, four.depth)
    left, right = card_region()
    # Inside flat regions the averaged colour is the same; at the card's edges it blends.
    assert np.abs(one.rgb[left].astype(int) - four.rgb[left]).max() <= 1
    edges = (one.rgb != four.rgb).any(-1)
    assert edges.sum() > 20


def test_spot_light_cone(cell):
    floor = quad("floor", [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], GREY)
    spot = Light("spot", "spot", np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]), intensity=1.0, cone_deg=20.0)
    frame = renderer(Scene([floor], [spot], LabelTable()), cell, RaycastOptions(ambient=0.0), shadow_samples=0).render(
        CAMERA, look_at([0.0, -0.01, 2.0], [0, 0, 0]), {}
    )
    p = back_project(frame.depth.astype(float), CAMERA, look_at([0.0, -0.01, 2.0], [0, 0, 0]))
    r = np.linalg.norm(p[..., :2], axis=-1)
    inside, outside = r < np.tan(np.radians(15)), r > np.tan(np.radians(21))
    assert (frame.rgb[inside][:, 0] > 100).all() and (frame.rgb[outside] == 0).all()


# ------------------------------------------------------------------------------ robots


def test_arms_are_drawn_at_their_link_poses(cell, kin):
    """The real cell (fixture ``cell``: build_cell(CellConfig())) with link poses from
    ArmKinematics: a camera looking at an arm sees it unless hide_robots."""
    arm = cell.arm("r1")
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    elbow = poses["r1"]["forearm_link"][:3, 3]
    T = look_at(elbow + np.array([0.0, -1.5, 0.3]), elbow)
    scene = Scene([], LIGHTS, LabelTable())
    seen = renderer(scene, cell, shadow_samples=1, hide_robots=False).render(CAMERA, T, poses)
    hidden = renderer(scene, cell, shadow_samples=1, hide_robots=True).render(CAMERA, T, poses)
    assert (hidden.depth == 0).all() and (hidden.rgb == 0).all()
    assert (seen.depth > 0).mean() > 0.02
    assert 1.2 < seen.depth[60, 80] < 1.55  # the forearm's near side, at the image centre
    assert (seen.labels == 0).all()  # arms are never labelled
    # Moving the arm moves its image.
    q = np.array(arm.home) + [0.6, 0, 0, 0, 0, 0]
    moved = dict(poses, r1=kin["r1"].link_poses(q))
    other = renderer(scene, cell, shadow_samples=0, hide_robots=False).render(CAMERA, T, moved)
    assert ((other.depth > 0) != (seen.depth > 0)).mean() > 0.01


def test_arms_posed_by_instances_match_arms_built_into_the_scene(cell, kin):
    """Arms are placed per frame by their instances' transforms; the same arms baked into the
    static scene at the same link poses (world-frame vertices) give the same labels, depth to
    float32 rounding and RGB but for rounding (the arms' shadows on a cut-out card and a floor
    included)."""
    from agrisim.plugins.render.arm_visuals import arm_link_meshes

    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    elbow = poses["r1"]["forearm_link"][:3, 3]
    scene = shadow_scene(True)
    for mesh in scene.meshes:
        mesh.vertices = mesh.vertices + [elbow[0], elbow[1], 0.0]
    light = dataclasses.replace(scene.lights[0], position=elbow + [0.0, 0.0, 1.5])
    scene = Scene(scene.meshes, [light], scene.labels, plant="plant")
    baked = []
    for arm in cell.arms:
        for lm in arm_link_meshes(arm.urdf, RaycastOptions().arm_triangles):
            T = poses[arm.name][lm.link]
            m = lm.mesh
            baked.append(dataclasses.replace(m, vertices=m.vertices @ T[:3, :3].T + T[:3, 3]))
    baked_scene = Scene(scene.meshes + baked, [light], scene.labels, plant="plant")
    T = look_at(elbow + np.array([0.3, -1.8, 0.9]), [elbow[0], elbow[1], 0.3])
    posed = renderer(scene, cell, shadow_samples=2, hide_robots=False).render(CAMERA, T, poses)
    built = renderer(baked_scene, cell, shadow_samples=2, hide_robots=True).render(CAMERA, T, poses)
    hidden = renderer(scene, cell, shadow_samples=2, hide_robots=True).render(CAMERA, T, poses)
    assert (posed.labels > 0).mean() > 0.005  # the card
    assert (posed.depth != hidden.depth).mean() > 0.01  # an arm ...
    assert (posed.rgb != hidden.rgb).any(-1).mean() > 0.05  # ... and its shadow
    same = np.abs(posed.depth - built.depth) < 1e-5
    assert same.mean() > 0.999  # (a ray grazing an arm's edge may pass one and hit the other)
    np.testing.assert_array_equal(posed.labels, built.labels)
    close = np.abs(posed.rgb.astype(int) - built.rgb).max(-1) <= 1
    assert close.mean() > 0.999


def test_views_after_the_first_compile_no_kernel(cell, kin):
    """Per-view values (camera pose, image size, arm poses, the view's seed) reach the kernels as
    data, not as constants: after a run's first view, Dr.Jit's kernel history shows every kernel
    found in its cache, none compiled."""
    import drjit as dr

    from agrisim.scene.camera import from_fov

    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    moved = {a.name: kin[a.name].link_poses(np.array(a.home) + 0.2) for a in cell.arms}
    r = renderer(shadow_scene(True), cell, shadow_samples=2, hide_robots=False, seg_mode="repopa")
    r.render(CAMERA, SHADOW_T, poses)  # the first view compiles
    other_T = look_at([0.4, -1.2, 1.5], [0.0, 0.0, 0.2])
    for camera, T, links in ((CAMERA, other_T, moved), (from_fov(50.0, 96, 64), SHADOW_T, poses)):
        dr.kernel_history()  # (empties the history)
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            frame = r.render(camera, T, links)
            jit = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
        assert frame.rgb.shape == (camera.height, camera.width, 3) and (frame.depth > 0).any()
        assert jit and all(k["cache_hit"] for k in jit), [k["hash"] for k in jit if not k["cache_hit"]]


def test_arms_left_out_of_the_link_poses_are_not_drawn(cell, kin):
    """An arm that a frame gives no link poses for is left out (its instances parked), and comes
    back when it has them again."""
    poses = {a.name: kin[a.name].link_poses(np.array(a.home)) for a in cell.arms}
    elbow = poses["r1"]["forearm_link"][:3, 3]
    T = look_at(elbow + np.array([0.0, -1.5, 0.3]), elbow)
    r = renderer(Scene([], LIGHTS, LabelTable()), cell, shadow_samples=0, hide_robots=False)
    both = r.render(CAMERA, T, poses)
    without = r.render(CAMERA, T, {"r2": poses["r2"]})
    again = r.render(CAMERA, T, poses)
    assert (both.depth > 0).mean() > 0.02 and not (without.depth > 0).any()
    np.testing.assert_array_equal(again.depth, both.depth)


def test_a_variant_that_cannot_run_is_refused_before_the_run_naming_raycast():
    from agrisim.errors import ConfigError
    from agrisim.plugins.render import raycast
    from agrisim.plugins.render.mitsuba.variant import _backends

    (spec,) = raycast.agrisim_renderers()
    if _backends()[0]:
        pytest.skip("CUDA is usable here: variant 'cuda' runs")
    with pytest.raises(ConfigError, match=r"^\[renderer\.raycast\] variant 'cuda' needs a usable NVIDIA GPU") as info:
        spec.preflight(None, RaycastOptions(variant="cuda"))
    assert "\n" not in str(info.value)
    spec.preflight(None, RaycastOptions(variant="auto"))  # the CPU serves
