"""The one mesh builder: parts keep their order, poses and materials; batches share faces."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from agrisim.plugins.mesh_builder import MeshBuilder
from agrisim.scene.model import Material
from agrisim.scene.transforms import translation, yaw_matrix

TRI = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), np.array([[0.0, 0], [1, 0], [0, 1]]))


def _triangles(mesh) -> np.ndarray:
    return mesh.vertices[mesh.faces]


def test_parts_keep_order_pose_and_material() -> None:
    red, blue = Material("red", (1, 0, 0, 1)), Material("blue", (0, 0, 1, 1))
    T = translation(0.5, -0.2, 1.0) @ yaw_matrix(0.7)
    b = MeshBuilder()
    b.add_part(TRI, red)
    b.add_part(TRI, blue, T)
    b.add_parts([TRI, TRI], red)
    whole = translation(0.0, 0.0, 2.0)
    mesh = b.build("m", T=whole)
    assert mesh.materials == [red, blue]  # first seen first, each once
    assert mesh.face_material.tolist() == [0, 1, 0, 0]
    assert mesh.face_instance is None  # nothing asked for instances
    expected = [TRI[0], trimesh.transform_points(TRI[0], T), TRI[0], TRI[0]]
    expected = [trimesh.transform_points(p, whole) for p in expected]
    np.testing.assert_allclose(_triangles(mesh), np.stack(expected), atol=1e-12)
    np.testing.assert_array_equal(mesh.uvs, np.tile(TRI[2], (4, 1)).astype(np.float32))


def test_batches_repeat_faces_and_carry_instances() -> None:
    b = MeshBuilder()
    items = np.stack([TRI[0] + k for k in range(3)])  # 3 items x 3 vertices
    ids = b.instances(3)
    b.add(items, TRI[1], None, material=0, instance=ids)
    b.add(TRI[0] * 2, TRI[1], TRI[2], material=1, instance=0)
    mesh = b.build("batch", [Material("a"), Material("b")])
    np.testing.assert_allclose(_triangles(mesh)[:3], items)
    np.testing.assert_allclose(_triangles(mesh)[3], TRI[0] * 2)
    assert mesh.face_instance.dtype == np.uint16 and mesh.face_instance.tolist() == [1, 2, 3, 0]
    assert b.instances(2).tolist() == [4, 5]
    r, zlo, zhi = b.bounds()
    assert r == pytest.approx(np.hypot(3.0, 2.0)) and (zlo, zhi) == (0.0, 2.0)


def test_too_many_instances_are_refused() -> None:
    b = MeshBuilder()
    b.add(TRI[0], TRI[1], None, 0, instance=70_000)
    with pytest.raises(ValueError, match="65535"):
        b.build("many", [Material("a")])
