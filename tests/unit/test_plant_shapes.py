"""Curved leaf blades (``strip_cards``, ``plate_cards``): the shape each parameter promises,
checked against closed forms on straight cards, and the mesh within :data:`SAG` (half a pixel
at 1080p from 0.3 m) of the surface it stands for, checked against the same surface sampled
sixteen times finer."""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.plugins.plants.procedural import shapes
from agrisim.plugins.plants.procedural.shapes import plate_cards, strip_cards

ATLAS = 512
RECT = np.array([[10.0, 10.0, 201.0, 61.0]])  # a tile 201 texels long, 61 wide: aspect 0.3


def grid_of(uv: np.ndarray) -> tuple[int, int]:
    """(rows, cols) of one card's vertex grid, from its UVs (u follows t across, v follows s)."""
    return len(np.unique(np.round(uv[:, 1], 9))) - 1, len(np.unique(np.round(uv[:, 0], 9))) - 1


def off_surface(coarse: np.ndarray, shape: tuple[int, int], fine: np.ndarray, fine_shape: tuple[int, int]) -> float:
    """Largest distance, along the fine grid's normals, between the fine vertices and the coarse
    grid's triangles (as ``grid_faces`` splits each cell: a-b-e above the diagonal, a-e-d below)
    at the same parameters; the fine grid's rows and columns are multiples of the coarse's."""
    (r, c), (R, C) = shape, fine_shape
    kr, kc = R // r, C // c
    assert kr * r == R and kc * c == C, (shape, fine_shape)
    g = coarse.reshape(-1, r + 1, c + 1, 3)
    f = fine.reshape(-1, R + 1, C + 1, 3)
    normals = shapes.unit(np.cross(np.gradient(f, axis=1), np.gradient(f, axis=2)))
    rows_f, cols_f = np.meshgrid(np.arange(R + 1), np.arange(C + 1), indexing="ij")
    i, j = np.minimum(rows_f // kr, r - 1), np.minimum(cols_f // kc, c - 1)
    u, v = (rows_f - i * kr) / kr, (cols_f - j * kc) / kc  # within the cell: u along the rows, v across
    a, b, d, e = g[:, i, j], g[:, i, j + 1], g[:, i + 1, j], g[:, i + 1, j + 1]
    upper = (v >= u)[None, ..., None]
    p = np.where(
        upper,
        a + v[None, ..., None] * (b - a) + u[None, ..., None] * (e - b),
        a + u[None, ..., None] * (d - a) + v[None, ..., None] * (e - d),
    )
    return float(np.abs(np.sum((p - f) * normals, axis=-1)).max())


#: the most curved blades the species grow: the Boston fern's frond (arch, twist, trough), the
#: Chinese evergreen's leaf (rippled margins), coltsfoot's round leaf (rim ripple, hanging
#: tip, drawn in onto an octagon)
CARDS = {
    "frond": lambda: strip_cards(
        np.zeros((1, 3)),
        0.3,
        1.2,
        0.32,
        np.array([[0, 0, 961.0, 164.0]]),
        1024,
        segments=10,
        bend=2.8,
        bend_power=1.4,
        curl=0.5,
        twist=1.2,
        fold=0.12,
        cup=0.3,
    ),
    "rippled leaf": lambda: strip_cards(
        np.zeros((1, 3)),
        0.3,
        0.6,
        0.2,
        RECT,
        ATLAS,
        segments=6,
        bend=1.0,
        bend_power=1.5,
        fold=0.18,
        twist=0.5,
        cup=0.2,
        wave=0.15,
        waves=3,
        phase=0.7,
    ),
    "round leaf": lambda: plate_cards(
        np.zeros((1, 3)),
        np.array([[0.2, 0.1, 1.0]]),
        0.4,
        0.13,
        np.array([[0, 0, 101.0, 101.0]]),
        ATLAS,
        cup=-0.1,
        wave=0.06,
        waves=9,
        phase=0.3,
        droop=0.25,
        corner=0.7,
        anchor=0.3,
    ),
}


def built(card: str, monkeypatch) -> tuple[np.ndarray, tuple[int, int]]:
    """(vertices, (rows, cols) of the grid the refinement chose) of one of :data:`CARDS`."""
    chosen = []
    refined = shapes.refined

    def spy(*args, **kwargs):
        chosen.append(refined(*args, **{**kwargs, "limit": 4096}))
        return chosen[-1]

    monkeypatch.setattr(shapes, "refined", spy)
    V = CARDS[card]()[0]
    monkeypatch.setattr(shapes, "refined", refined)
    return V, chosen[-1]


@pytest.mark.parametrize("card", list(CARDS))
def test_curved_blades_lie_within_half_a_pixel_of_their_surface(card, monkeypatch):
    V, shape = built(card, monkeypatch)
    sag = shapes.SAG
    monkeypatch.setattr(shapes, "SAG", sag / 16)
    fine, fine_shape = built(card, monkeypatch)
    assert fine_shape[0] > shape[0] or fine_shape[1] > shape[1]
    assert off_surface(V, shape, fine, fine_shape) <= 4 / 3 * sag  # (SAG is met against twice as fine)


def test_a_straight_blade_rises_across_as_its_fold_cup_and_wave_say():
    """A level card along +x (no arch): its normal is -z (the side an arching blade turns to the
    ground) and each vertex at (t, s) sits half-width x (fold |t| + cup t^2 + wave |t|^3
    sin(2 pi waves s + phase) ramp(s)) along it from the midrib, where ramp rises from 0 to 1
    over the first 15% of the length."""
    fold, cup, wave, waves, phase, length = 0.1, 0.25, 0.12, 3.0, 0.4, 0.2
    V, _, UV, C = strip_cards(
        np.zeros((1, 3)), 0.0, 0.0, length, RECT, ATLAS, fold=fold, cup=cup, wave=wave, waves=waves, phase=phase
    )
    rows, cols = grid_of(UV[0])
    assert cols >= 8  # the cup and ripple made it subdivide across
    grid = V[0].reshape(rows + 1, cols + 1, 3)
    t = np.linspace(-1, 1, cols + 1)[None, :]
    s = np.linspace(0, 1, rows + 1)[:, None]
    half = 0.5 * 0.3 * length
    rise = half * (
        fold * np.abs(t)
        + cup * t**2
        + wave * np.abs(t) ** 3 * np.sin(2 * np.pi * waves * s + phase) * np.clip(s / 0.15, 0, 1)
    )
    np.testing.assert_allclose(grid[..., 2], -rise, atol=1e-12)
    np.testing.assert_allclose(grid[..., 1], t * half + 0 * s, atol=1e-12)  # across: +y for a heading +x
    np.testing.assert_allclose(grid[..., 0], s * length + 0 * t, atol=1e-12)


def test_a_plate_cups_ripples_and_droops_as_it_says():
    """A level plate facing +z: each vertex sits size x (cup r^2 + wave r^3 sin(waves theta +
    phase) - droop max(y, 0)^2) above its centre, (x, y) its place in the plate in sizes."""
    cup, wave, waves, phase, droop, size = -0.08, 0.05, 7.0, 0.2, 0.2, 0.1
    V, _, UV = plate_cards(
        np.zeros((1, 3)),
        np.array([[0.0, 0.0, 1.0]]),
        0.0,
        size,
        np.array([[0, 0, 101.0, 101.0]]),
        ATLAS,
        cup=cup,
        wave=wave,
        waves=waves,
        phase=phase,
        droop=droop,
    )
    e1, e2 = shapes.frame(np.array([[0.0, 0.0, 1.0]]), np.zeros(1))
    x, y = V[0] @ e1[0] / size, V[0] @ e2[0] / size
    r, theta = np.hypot(x, y), np.arctan2(x, y)
    expected = size * (cup * r**2 + wave * r**3 * np.sin(waves * theta + phase) - droop * np.maximum(y, 0) ** 2)
    np.testing.assert_allclose(V[0][:, 2], expected, atol=1e-12)
    assert np.ptp(V[0][:, 2]) > 0.2 * size * abs(cup)


def test_stems_taper_from_their_base_to_their_end():
    """A stem given one radius is a tube whose rings shrink linearly from that radius at its
    base to TAPER of it at its end (its vertices' distances from the straight axis)."""
    from agrisim.plugins.mesh_builder import MeshBuilder
    from agrisim.plugins.plants.procedural.growing import TAPER, add_tubes

    b = MeshBuilder()
    path = np.stack([np.zeros(5), np.zeros(5), np.linspace(0.0, 0.2, 5)], axis=-1)[None]
    add_tubes(b, path, 0.004, sides=6)
    rings = b.vertices[0].reshape(5, 6, 3)
    radii = np.hypot(rings[..., 0], rings[..., 1])
    np.testing.assert_allclose(radii, np.linspace(0.004, 0.004 * TAPER, 5)[:, None].repeat(6, 1), rtol=1e-12)
    assert TAPER < 0.9
