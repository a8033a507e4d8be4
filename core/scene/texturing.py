"""Texture lookups shared by renderers, exporters and metrics.

UVs follow glTF (origin top-left, v down); lookups are *nearest* texel, wrapping, which is
exactly how the paper samples its label texture (a label must never blend into another).
"""

from __future__ import annotations

import numpy as np

from agrisim.scene.model import Material, Mesh


def texel_index(uv: np.ndarray, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the texels nearest ``uv`` (K x 2), wrapping outside [0, 1)."""
    uv = np.asarray(uv, dtype=np.float64)
    cols = np.floor(uv[:, 0] * width).astype(np.int64) % width
    rows = np.floor(uv[:, 1] * height).astype(np.int64) % height
    return rows, cols


def sample_nearest(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Texels of ``image`` (H x W or H x W x C) nearest each UV (K x 2)."""
    rows, cols = texel_index(uv, image.shape[0], image.shape[1])
    return image[rows, cols]


def interpolate(mesh: Mesh, values: np.ndarray, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Per-vertex ``values`` (N x C) at points given by face indices (K,) and barycentric
    (u, v) of Open3D/Embree convention: point = (1 - u - v) * A + u * B + v * C."""
    tri = mesh.faces[faces]
    w1, w2 = bary[:, 0:1], bary[:, 1:2]
    return (1.0 - w1 - w2) * values[tri[:, 0]] + w1 * values[tri[:, 1]] + w2 * values[tri[:, 2]]


def interpolate_uv(mesh: Mesh, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """UVs at points given by face indices and barycentrics (:func:`interpolate`)."""
    assert mesh.uvs is not None
    return interpolate(mesh, mesh.uvs, faces, bary)


def opaque(material: Material, uv: np.ndarray) -> np.ndarray:
    """Does each UV land on a texel that is not cut away? (bool, K)"""
    if not material.cuts:
        return np.ones(len(uv), dtype=bool)
    factor = float(material.color[3])
    if material.albedo is None:
        return np.full(len(uv), factor >= material.alpha_cutoff)
    # glTF: alpha = texture alpha x factor alpha; texture alpha 128/255 passes a 0.5 cutoff
    alpha = sample_nearest(material.albedo, uv)[:, 3].astype(np.float64) / 255.0
    return alpha * factor >= material.alpha_cutoff


def alpha_threshold(material: Material) -> int:
    """Smallest 8-bit texture alpha that ``material`` keeps (0 when opacity cuts nothing; 256
    when it keeps nothing). glTF: alpha is the texel's times the colour factor's, compared with
    the same float operations as :func:`agrisim.scene.texturing.opaque`; an untextured material reads
    a white texel (alpha 255)."""
    if not material.cuts:
        return 0
    ok = np.arange(256, dtype=np.float64) / 255.0 * float(material.color[3]) >= material.alpha_cutoff
    return int(np.argmax(ok)) if ok.any() else 256


def label_at(material: Material, uv: np.ndarray) -> np.ndarray:
    """Label id of each UV's texel (uint8, K)."""
    if material.labels is None:
        return np.full(len(uv), material.label, dtype=np.uint8)
    return sample_nearest(material.labels, uv)


def sample_triangles(
    vertices: np.ndarray, faces: np.ndarray, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` points uniformly by area on triangles: (points K x 3, faces K, barycentrics
    K x 2 as weights of the second and third corners)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    total = areas.sum()
    if total <= 0:
        raise ValueError("the triangles have no area")
    chosen = rng.choice(len(areas), size=count, p=areas / total)
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    bary = np.column_stack([s * (1 - r2), s * r2])
    tri = vertices[faces[chosen]]
    points = (1 - bary[:, :1] - bary[:, 1:]) * tri[:, 0] + bary[:, :1] * tri[:, 1] + bary[:, 1:] * tri[:, 2]
    return points, chosen, bary


def sample_surface(mesh: Mesh, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``count`` points uniformly by area: (points K x 3, faces K, barycentrics K x 2)."""
    if mesh.areas.sum() <= 0:
        raise ValueError(f"mesh {mesh.name!r} has no area")
    return sample_triangles(mesh.vertices, mesh.faces, count, rng)


def opaque_samples(mesh: Mesh, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """For surface samples (faces, barycentrics): is each on an opaque texel? (bool, K)"""
    keep = np.ones(len(faces), dtype=bool)
    if mesh.uvs is None:
        return keep
    uv = interpolate_uv(mesh, faces, bary)
    mats = mesh.face_material[faces]
    for i in np.unique(mats):
        sel = mats == i
        keep[sel] = opaque(mesh.materials[i], uv[sel])
    return keep


def labels_at_samples(mesh: Mesh, faces: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Label id at surface samples (faces, barycentrics), from each material's label texture or
    constant label (uint8, K)."""
    out = np.zeros(len(faces), dtype=np.uint8)
    uv = interpolate_uv(mesh, faces, bary) if mesh.uvs is not None else np.zeros((len(faces), 2))
    mats = mesh.face_material[faces]
    for i in np.unique(mats):
        sel = mats == i
        out[sel] = label_at(mesh.materials[i], uv[sel])
    return out


def cutaway_fraction(mesh: Mesh, samples: int = 200_000, seed: int = 0) -> float:
    """Fraction of the mesh's area that opacity cuts away (Monte Carlo over the surface)."""
    _, faces, bary = sample_surface(mesh, samples, np.random.default_rng(seed))
    return float(1.0 - opaque_samples(mesh, faces, bary).mean())


def surface_summary(mesh: Mesh, samples: int = 200_000, seed: int = 0) -> tuple[float, int, float]:
    """(share of the area opacity cuts away, leaf instances, their opaque area in m^2) of a
    mesh, by the same surface samples (Monte Carlo; agrisim.plugins.apps.traits measures the area exactly)."""
    _, faces, bary = sample_surface(mesh, samples, np.random.default_rng(seed))
    kept = opaque_samples(mesh, faces, bary)
    if mesh.face_instance is None:
        return float(1.0 - kept.mean()), 0, 0.0
    on_leaf = mesh.face_instance[faces] > 0
    leaves = int(len(np.unique(mesh.face_instance[mesh.face_instance > 0])))
    return float(1.0 - kept.mean()), leaves, float(mesh.areas.sum() * np.mean(kept & on_leaf))
