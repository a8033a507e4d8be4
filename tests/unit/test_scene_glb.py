"""The saved scene (``OUT/scene/lab.glb``): what a run renders, read back exactly, so that
``agrisim render`` draws the same scene. Truth: the scene the run built."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agrisim.errors import UserError
from agrisim.plugins.formats.scene_glb import read_scene
from agrisim.plugins.plants.procedural import grow
from agrisim.plugins.render.arm_visuals import arm_link_meshes
from agrisim.plugins.rooms.lab.room import build_scene
from agrisim.plugins.sinks.dataset.glb import export_glb
from agrisim.plugins.sinks.dataset.scene_glb import write_scene


@pytest.fixture(scope="module")
def lab(cell):  # noqa: ANN001, ANN201
    scene = build_scene(cell, grow("hydrangea", 3), labels="organs")
    arms = {a.name: [(lm.link, lm.mesh) for lm in arm_link_meshes(a.urdf, 30000)] for a in cell.arms}
    return dataclasses.replace(scene, arms=arms)


def assert_same_mesh(a, b) -> None:  # noqa: ANN001
    """Vertices equal in float32 (as stored), the same triangles with the same materials (the
    writer may group faces by material), UVs, vertex colours, material settings, texels and
    leaf instances."""
    assert a.name == b.name
    np.testing.assert_array_equal(a.vertices.astype(np.float32), b.vertices)
    names_a = [m.name for m in a.materials]
    names_b = [m.name for m in b.materials]
    fa = sorted((names_a[i], tuple(f)) for i, f in zip(a.face_material.tolist(), a.faces.tolist(), strict=True))
    fb = sorted((names_b[i], tuple(f)) for i, f in zip(b.face_material.tolist(), b.faces.tolist(), strict=True))
    assert fa == fb
    if a.uvs is None:
        assert b.uvs is None
    else:
        np.testing.assert_array_equal(a.uvs, b.uvs)
    for ma in a.materials:
        mb = next(m for m in b.materials if m.name == ma.name)
        for f in ("color", "label", "alpha_mode", "alpha_cutoff", "double_sided", "roughness", "metallic"):
            assert getattr(ma, f) == getattr(mb, f), (ma.name, f)
        assert (ma.transmittance is None) == (mb.transmittance is None)
        if ma.transmittance is not None:
            assert tuple(ma.transmittance) == tuple(mb.transmittance)
        for f in ("albedo", "labels"):
            if getattr(ma, f) is None:
                assert getattr(mb, f) is None
            else:
                np.testing.assert_array_equal(getattr(ma, f), getattr(mb, f))
    if a.colors is None:
        assert b.colors is None
    else:
        np.testing.assert_array_equal(a.colors, b.colors)
    if a.face_instance is not None:
        order_a = sorted(zip(a.faces.tolist(), a.face_instance.tolist(), strict=True))
        order_b = sorted(zip(b.faces.tolist(), b.face_instance.tolist(), strict=True))
        assert order_a == order_b


def test_the_lab_reads_back_as_it_was_written(lab, tmp_path):
    path = tmp_path / "lab.glb"
    write_scene(path, lab)
    back = read_scene(path)
    assert back.plant == lab.plant
    assert back.labels == lab.labels
    assert [m.name for m in back.meshes] == [m.name for m in lab.meshes if len(m.faces)]
    for a, b in zip([m for m in lab.meshes if len(m.faces)], back.meshes, strict=True):
        assert_same_mesh(a, b)
    assert len(back.lights) == len(lab.lights)
    for a, b in zip(lab.lights, back.lights, strict=True):
        assert dataclasses.astuple(a)[0:2] == dataclasses.astuple(b)[0:2]
        np.testing.assert_array_equal(a.position, b.position)
        np.testing.assert_array_equal(a.direction, b.direction)
        assert (a.color, a.intensity, a.radius, a.cone_deg) == (b.color, b.intensity, b.radius, b.cone_deg)
    assert list(back.arms) == list(lab.arms)
    for robot in lab.arms:
        assert [link for link, _ in back.arms[robot]] == [link for link, _ in lab.arms[robot]]
        for (_, a), (_, b) in zip(lab.arms[robot], back.arms[robot], strict=True):
            assert_same_mesh(a, b)


def test_a_plant_glb_is_not_a_scene(lab, tmp_path):
    export_glb(lab.mesh("plant"), tmp_path / "plant.glb", lab.labels)
    with pytest.raises(UserError, match="not a scene saved by agrisim"):
        read_scene(tmp_path / "plant.glb")
