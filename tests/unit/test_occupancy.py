"""The views' voxel map (agrisim.plugins.apps.nextview.occupancy) against analytic geometry: a camera facing
a wall frees the voxels in front of it, occupies the wall's and leaves those behind unknown; the
information gain of a view is the unknown voxels its rays reach before an occupied one."""

from __future__ import annotations

import numpy as np

from agrisim.plugins.apps.nextview.occupancy import FREE, OCCUPIED, PLANT, UNKNOWN, VoxelMap
from agrisim.scene.camera import from_fov
from agrisim.scene.transforms import look_at


def test_a_wall_seen_head_on() -> None:
    """A 1 m cube of 20 cells (5 cm) around the origin; a camera at x = -1.2 looks along +x at a
    wall x = 0.12 filling its view (depth = 1.32 m on every pixel), labelled plant in its
    left half."""
    vmap = VoxelMap.around(np.zeros(3), 1.0, 20)
    camera = from_fov(30.0, 64, 48)
    pose = look_at(np.array([-1.2, 0.0, 0.0]), np.zeros(3))
    depth = np.full((48, 64), 1.32, np.float32)
    labels = np.zeros((48, 64), np.uint8)
    labels[:, :32] = 1
    vmap.integrate(camera, pose, depth, labels, stride=1)
    x = (np.arange(20) + 0.5) * 0.05 - 0.5  # voxel centres
    # the view's footprint at x = 0.12 spans |y| < 0.35, |z| < 0.27: the middle rows and columns
    mid = vmap.cells[:, 8:12, 8:12]
    assert np.all(mid[x < 0.07] == FREE)  # in front of the wall's voxel (0.10 to 0.15)
    assert np.all(mid[(x > 0.1) & (x < 0.15)] >= OCCUPIED)
    assert np.all(mid[x > 0.16] == UNKNOWN)  # behind the wall
    wall = vmap.cells[12]
    assert PLANT in wall and OCCUPIED in wall and not np.any(wall == FREE)
    # the same view again learns nothing (its rays, 1.5 m long, stop at the wall); one from
    # behind the wall reaches its unknown side
    assert vmap.information_gain(camera, pose) == 0
    behind = look_at(np.array([1.2, 0.0, 0.0]), np.zeros(3))
    gain = vmap.information_gain(camera, behind, rays=(64, 48))
    unknown_behind = int(np.sum(vmap.cells[13:, 6:14, 7:13] == UNKNOWN))
    assert gain >= unknown_behind > 0


def test_a_plant_surface_has_two_sides() -> None:
    """The wall as plant, seen from its front: every voxel of it has its front side seen (the
    normal the depth gives points back at the camera), so a second look from the front finds no
    unseen side; a look from behind finds its back sides, on top of the unknown voxels."""
    vmap = VoxelMap.around(np.zeros(3), 1.0, 20)
    camera = from_fov(30.0, 64, 48)
    front = look_at(np.array([-1.2, 0.0, 0.0]), np.zeros(3))
    vmap.integrate(camera, front, np.full((48, 64), 1.32, np.float32), np.ones((48, 64), np.uint8), stride=1)
    assert vmap.normals is not None and vmap.sides is not None
    wall = vmap.cells == PLANT
    assert wall.any() and np.all(vmap.sides[wall] == 1)
    assert np.allclose(vmap.normals[wall], [-1.0, 0.0, 0.0], atol=1e-6)
    assert vmap.information_gain(camera, front, surface=True) == 0
    behind = look_at(np.array([1.2, 0.0, 0.0]), np.zeros(3))
    volume, surface = vmap.information_gain(camera, behind), vmap.information_gain(camera, behind, surface=True)
    assert surface - volume > 0.5 * int(wall.sum())


def test_each_ray_marched_to_its_own_length_meets_the_same_voxels() -> None:
    """The marching that frees a view's voxels samples each ray only as far as it goes; it meets
    the same voxels as marching every ray to the longest one's length and keeping the samples
    before each ray's end (rays from outside and inside the cube, short, long and endless)."""
    rng = np.random.default_rng(3)
    vmap = VoxelMap.around(np.array([0.1, -0.2, 0.3]), 0.5, 40)
    for origin in (np.array([0.1, -0.2, 0.3]), np.array([0.9, 0.4, 0.8])):
        directions = rng.normal(size=(500, 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        lengths = np.where(rng.random(500) < 0.2, np.inf, rng.uniform(0.0, 1.5, 500))
        index, live = vmap._march(origin, directions, lengths)
        dense = np.ravel_multi_index(tuple(index[live].T), vmap.cells.shape)
        flat = vmap._march_flat(origin, directions, lengths)
        assert len(dense) > 100
        np.testing.assert_array_equal(np.sort(flat), np.sort(dense))
