"""The arms' visual meshes kept on disk (``agrisim.robot.visuals``): a later process reads the
very meshes that loading the URDF's files and decimating them gives, and a change to anything
they are made from (the URDF, the triangle budget, a mesh file) makes them anew."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

from agrisim.config import CellConfig
from agrisim.robot import visuals
from agrisim.scene.cell import build_cell


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("AGRISIM_CACHE_DIR", str(tmp_path / "cache"))
    visuals.arm_link_meshes.cache_clear()
    yield tmp_path / "cache" / "arm-visuals"
    visuals.arm_link_meshes.cache_clear()


def same(a, b) -> bool:  # noqa: ANN001
    return [lm.link for lm in a] == [lm.link for lm in b] and all(
        np.array_equal(x.mesh.vertices, y.mesh.vertices)
        and np.array_equal(x.mesh.faces, y.mesh.faces)
        and np.array_equal(x.mesh.face_material, y.mesh.face_material)
        and [m.color for m in x.mesh.materials] == [m.color for m in y.mesh.materials]
        for x, y in zip(a, b, strict=True)
    )


def test_a_later_process_reads_the_decimated_arm(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    urdf = build_cell(CellConfig()).arms[0].urdf
    made = visuals.arm_link_meshes(urdf, 20_000)
    assert len(list(cache.glob("*.pickle"))) == 1
    truth = visuals._link_meshes(urdf, 20_000)
    assert same(made, truth) and 0.9 * 20_000 < sum(len(lm.mesh.faces) for lm in made) < 1.1 * 20_000
    visuals.arm_link_meshes.cache_clear()  # as a new process finds it

    def refuse(*_: object) -> None:
        raise AssertionError("made again")

    monkeypatch.setattr(visuals, "_link_meshes", refuse)
    assert same(visuals.arm_link_meshes(urdf, 20_000), truth)


def box_urdf(mesh: Path) -> str:
    return (
        '<robot name="r"><link name="base"><visual><geometry><box size="0.1 0.2 0.3"/></geometry></visual>'
        f'<visual><geometry><mesh filename="{mesh}"/></geometry></visual></link></robot>'
    )


def test_what_the_meshes_are_made_from_names_the_entry(cache: Path, tmp_path: Path) -> None:
    part = tmp_path / "part.stl"
    trimesh.creation.icosphere(subdivisions=4).export(part)
    urdf = box_urdf(part)
    first = visuals.arm_link_meshes(urdf, 0)
    visuals.arm_link_meshes(urdf, 500)  # another budget: decimated, another entry
    assert len(list(cache.glob("*.pickle"))) == 2
    trimesh.creation.icosphere(subdivisions=2).export(part)  # the file changes
    os.utime(part, ns=(part.stat().st_atime_ns, part.stat().st_mtime_ns + 10**9))
    visuals.arm_link_meshes.cache_clear()
    changed = visuals.arm_link_meshes(urdf, 0)
    assert len(list(cache.glob("*.pickle"))) == 3
    assert len(changed[0].mesh.faces) < len(first[0].mesh.faces)
    visuals.arm_link_meshes(urdf.replace("0.1 0.2 0.3", "0.1 0.2 0.4"), 0)  # the URDF changes
    assert len(list(cache.glob("*.pickle"))) == 4


def test_a_broken_entry_is_made_again(cache: Path, tmp_path: Path) -> None:
    part = tmp_path / "part.stl"
    trimesh.creation.icosphere(subdivisions=3).export(part)
    urdf = box_urdf(part)
    truth = visuals.arm_link_meshes(urdf, 0)
    (entry,) = cache.glob("*.pickle")
    entry.write_bytes(b"not a pickle")
    visuals.arm_link_meshes.cache_clear()
    assert same(visuals.arm_link_meshes(urdf, 0), truth)
