"""How good a reconstruction is, measured against the plant the simulator knows exactly.

The ground truth is the plant's surface sampled uniformly by area, keeping only samples on
texels whose opacity passes the material's cutoff (what a camera can actually see of a leaf
card). For a reconstructed point the distance to that surface is exact where the nearest point of
the whole mesh lies on an opaque texel of the point's label (Open3D's closest-point query), and
the distance to the nearest ground-truth sample otherwise. Reported per label and for ``all``:

* precision@d: share of reconstructed points within d of the true surface,
* recall@d: share of true-surface samples within d of a reconstructed point, also counted over
  only the samples seen by at least one camera (``recall_visible``: hidden parts such as stems
  inside the soil cannot be reconstructed by any method),
* F-score@d (harmonic mean of the two) and the Chamfer distance (mean of the mean distances in
  both directions, mm).
* thickness (``all`` only, with a true surface): twice the median distance of the points from
  the surface along its normal, mm; a card reconstructed is about as thin as the depth's
  rounding, a plant drawn as spheres about as thick as their diameter.

A scanned point plant has no surface: its points are the truth (distances to the nearest).

Per-view counts (labelled pixels, which samples were seen, leaf instances) accumulate in
:class:`ViewStats` while views stream, so no image is kept.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agrisim.evaluation.views import View
from agrisim.interfaces import ALL, Reconstruction
from agrisim.scene.encoding import depth_to_mm
from agrisim.scene.model import LabelTable, Mesh, PointSet, Scene
from agrisim.scene.texturing import labels_at_samples, opaque_samples, sample_surface, sample_triangles

#: how densely reconstructed meshes are sampled to be measured, points per square metre
MESH_SAMPLES_PER_M2 = 4.0e6  # 0.5 mm spacing
MESH_SAMPLES_MAX = 3_000_000


@dataclass
class GroundTruth:
    """Opaque samples of the true plant surface in world coordinates, with their labels.

    A scanned point plant has no surface: its points are the truth (``mesh`` is None and
    distances go to the nearest point)."""

    mesh: Mesh | None
    points: np.ndarray  # (K, 3)
    labels: np.ndarray  # (K,) uint8 label ids of the run's table
    area_m2: float | None  # opaque area of the plant, estimated from the samples (None: points only)
    normals: np.ndarray | None = None  # (K, 3) unit normals of the samples' triangles (None: points only)
    instances: np.ndarray | None = None  # (K,) leaf instance of each sample, 0 off the leaves

    @classmethod
    def sample(cls, mesh: Mesh, count: int, seed: int = 0) -> GroundTruth:
        """Sample ``count`` points of ``mesh`` uniformly by area and keep the opaque ones."""
        points, faces, bary = sample_surface(mesh, count, np.random.default_rng(seed))
        keep = opaque_samples(mesh, faces, bary)
        labels = labels_at_samples(mesh, faces[keep], bary[keep])
        area = float(mesh.areas.sum()) * float(keep.mean())
        v = mesh.vertices[mesh.faces[faces[keep]]]
        normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
        instances = (
            np.zeros(len(normals), np.int64)
            if mesh.face_instance is None
            else mesh.face_instance[faces[keep]].astype(np.int64)
        )
        return cls(mesh, points[keep], labels, area, normals, instances)

    @classmethod
    def of_points(cls, points: PointSet, count: int, seed: int = 0) -> GroundTruth:
        """The truth of a plant that is only points: up to ``count`` of them (a seeded subset)."""
        idx = np.arange(len(points))
        if len(idx) > count:
            idx = np.sort(np.random.default_rng(seed).choice(len(idx), count, replace=False))
        return cls(None, points.positions[idx], points.labels[idx], None)

    @classmethod
    def of_scene(cls, scene: Scene, count: int, seed: int = 0) -> GroundTruth:
        """The truth of a scene's plant: its surface (the drawn mesh, or the one its points were
        sampled from), else its points."""
        surface = scene.plant_surface()
        if surface is not None:
            return cls.sample(surface, count, seed)
        assert scene.points is not None
        return cls.of_points(scene.points, count, seed)

    def select(self, label_id: int | None) -> np.ndarray:
        """Mask of the samples of ``label_id`` (None: every plant label)."""
        return self.labels != 0 if label_id is None else self.labels == label_id


def visible_samples(truth: GroundTruth, view: View, among: np.ndarray | None = None) -> np.ndarray:
    """Which ground-truth samples ``view`` sees (of the indices ``among``, default all): they
    project inside the image onto a pixel whose depth matches theirs (within the depth's
    millimetre rounding plus two pixel footprints of slope) and whose label is theirs."""
    idx = np.arange(len(truth.points)) if among is None else among
    cam = view.camera
    T = view.world_T_camera
    p = (truth.points[idx] - T[:3, 3]) @ T[:3, :3]  # camera_T_world applied: R^T (p - t)
    z = p[:, 2]
    seen = np.zeros(len(idx), bool)
    front = np.flatnonzero(z > 1e-6)
    zf = z[front]
    if cam.pinhole:
        col = np.rint(cam.fx * p[front, 0] / zf + cam.cx)
        row = np.rint(cam.fy * p[front, 1] / zf + cam.cy)
    else:
        col, row = (np.rint(c) for c in cam.project(p[front, 0] / zf, p[front, 1] / zf))
    inside = (col >= 0) & (col < cam.width) & (row >= 0) & (row < cam.height)
    k = front[inside]
    r, c = row[inside].astype(np.int64), col[inside].astype(np.int64)
    d = depth_to_mm(view.images.depth[r, c]).astype(np.float64) * 1e-3
    tol = 1e-3 + 2.0 * z[k] / cam.fx
    seen[k] = (d > 0) & (np.abs(d - z[k]) <= tol) & (view.images.labels[r, c] == truth.labels[idx[k]])
    return seen


@dataclass
class ViewStats:
    """Counts over the views of a run: labelled pixels per label id, ground-truth samples seen,
    leaf instance ids seen."""

    truth: GroundTruth | None = None
    frames: int = 0
    pixels: np.ndarray = field(default_factory=lambda: np.zeros(256, np.int64))
    instances: np.ndarray = field(default_factory=lambda: np.zeros(1 << 16, bool))
    has_instances: bool = False
    seen: np.ndarray | None = None

    def add(self, view: View) -> None:
        self.frames += 1
        labels, instances = view.images.labels, view.images.instances
        ids, counts = np.unique(labels[labels != 0], return_counts=True)
        self.pixels[ids] += counts
        if instances is not None:
            self.has_instances = True
            self.instances[np.unique(instances)] = True
        if self.truth is not None:
            if self.seen is None:
                self.seen = np.zeros(len(self.truth.points), bool)
            unseen = np.flatnonzero(~self.seen)  # a sample seen once stays seen: test the rest
            self.seen[unseen[visible_samples(self.truth, view, unseen)]] = True

    @property
    def leaf_instances_seen(self) -> int | None:
        """Distinct leaf instances seen in any frame (None when no frame had instances)."""
        return int(self.instances[1:].sum()) if self.has_instances else None


def nearest_distances(query: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Distance from every query point to its nearest reference point (inf without any)."""
    if len(reference) == 0:
        return np.full(len(query), np.inf)
    if len(query) == 0:
        return np.zeros(0)
    import open3d as o3d

    q = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(query, np.float64)))
    r = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(reference, np.float64)))
    return np.asarray(q.compute_point_cloud_distance(r))


class SurfaceDistance:
    """Distances from points to the true opaque surface (of one label, or of the whole plant)."""

    def __init__(self, truth: GroundTruth) -> None:
        import open3d as o3d

        self.truth = truth
        mesh = truth.mesh
        if mesh is None:
            return
        self.scene = o3d.t.geometry.RaycastingScene()
        # Open3D's stub gives Tensor(np_array, dtype, device) no defaults; the binding has them
        self.scene.add_triangles(
            o3d.core.Tensor(mesh.vertices.astype(np.float32)),  # type: ignore[call-overload]
            o3d.core.Tensor(mesh.faces.astype(np.uint32)),  # type: ignore[call-overload]
        )
        self._o3d = o3d

    def _closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(face, barycentrics, closest point) on the true surface for each point; the point in
        double precision from its barycentrics (the query runs in float32)."""
        mesh = self.truth.mesh
        assert mesh is not None
        # Tensor's stub: see __init__
        ans = self.scene.compute_closest_points(self._o3d.core.Tensor(points.astype(np.float32)))  # type: ignore[call-overload]
        faces = ans["primitive_ids"].numpy().astype(np.int64)
        bary = ans["primitive_uvs"].numpy().astype(np.float64)
        tri = mesh.vertices[mesh.faces[faces]]
        closest = (1 - bary[:, :1] - bary[:, 1:]) * tri[:, 0] + bary[:, :1] * tri[:, 1] + bary[:, 1:] * tri[:, 2]
        return faces, bary, closest

    def _offsets(self, points: np.ndarray, faces: np.ndarray, closest: np.ndarray) -> np.ndarray:
        mesh = self.truth.mesh
        assert mesh is not None
        a, b, c = (mesh.vertices[mesh.faces[faces, i]] for i in range(3))
        n = np.cross(b - a, c - a)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        return np.einsum("ij,ij->i", points - closest, n)

    def measure(self, points: np.ndarray, label_id: int | None) -> tuple[np.ndarray, np.ndarray | None]:
        """Distances to the surface (as calling this does) and :meth:`normal_offsets`, from one
        closest-point query."""
        if len(points) == 0:
            return np.zeros(0), None
        mesh = self.truth.mesh
        if mesh is None:  # points are the truth
            return nearest_distances(points, self.truth.points[self.truth.select(label_id)]), None
        faces, bary, closest = self._closest(points)
        dist = np.linalg.norm(points - closest, axis=1)
        exact = opaque_samples(mesh, faces, bary)
        labels = labels_at_samples(mesh, faces, bary)
        exact &= labels != 0 if label_id is None else labels == label_id
        if not exact.all():
            reference = self.truth.points[self.truth.select(label_id)]
            dist[~exact] = nearest_distances(points[~exact], reference)
        return dist, self._offsets(points, faces, closest)

    def __call__(self, points: np.ndarray, label_id: int | None) -> np.ndarray:
        return self.measure(points, label_id)[0]

    def normal_offsets(self, points: np.ndarray) -> np.ndarray | None:
        """Signed distance of each point from the nearest point of the true surface along that
        triangle's normal, m (None when the truth is only points): how far a reconstruction
        stands off the surface on either side, the apparent thickness of its leaves."""
        if self.truth.mesh is None or len(points) == 0:
            return None
        faces, _, closest = self._closest(points)
        return self._offsets(points, faces, closest)


def thickness_mm(offsets: np.ndarray | None) -> float | None:
    """The apparent thickness of a reconstructed leaf: twice the median distance of its points
    from the true surface along the surface normal, mm (a leaf seen from both sides shows up as
    two sheets about that far apart; a single-sided card as thin as the depth's rounding)."""
    if offsets is None or len(offsets) < 20:
        return None
    return float(2.0 * np.median(np.abs(offsets)) * 1e3)


def _key(threshold_mm: float) -> str:
    return f"{threshold_mm:g}"


def accuracy(
    precision_d: np.ndarray,
    recall_d: np.ndarray,
    seen: np.ndarray | None,
    thresholds_mm: list[float],
) -> dict[str, Any]:
    """Precision, recall (all and visible samples), F-score per threshold and the Chamfer
    distance from the two directions' distances (metres)."""
    out: dict[str, Any] = {"precision": {}, "recall": {}, "recall_visible": {}, "fscore": {}}
    for t in thresholds_mm:
        d = t * 1e-3
        p = float(np.mean(precision_d <= d)) if len(precision_d) else 0.0
        r = float(np.mean(recall_d <= d)) if len(recall_d) else 0.0
        rv = float(np.mean(recall_d[seen] <= d)) if seen is not None and seen.any() else None
        out["precision"][_key(t)] = p
        out["recall"][_key(t)] = r
        out["recall_visible"][_key(t)] = rv
        out["fscore"][_key(t)] = 2 * p * r / (p + r) if p + r > 0 else 0.0
    finite = np.isfinite(recall_d)
    if len(precision_d) and finite.any():
        out["chamfer_mm"] = float(0.5 * (precision_d.mean() + recall_d[finite].mean()) * 1e3)
    else:
        out["chamfer_mm"] = None
    return out


def measured_points(recon: Reconstruction, name: str) -> np.ndarray:
    """The points that stand for label ``name`` of a reconstruction: its cloud, or samples of
    its mesh surface (uniform by area, 0.5 mm apart) when it is a surface."""
    if name in recon.clouds:
        return recon.clouds[name].points
    mesh = recon.meshes.get(name)
    if mesh is None or len(mesh.triangles) == 0:
        return np.zeros((0, 3))
    a, b, c = (mesh.vertices[mesh.triangles[:, i]] for i in range(3))
    area = 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
    count = int(np.clip(area * MESH_SAMPLES_PER_M2, 1000, MESH_SAMPLES_MAX))
    points, _, _ = sample_triangles(mesh.vertices, mesh.triangles, count, np.random.default_rng(0))
    return points


def evaluate(
    recon: Reconstruction,
    labels: LabelTable,
    stats: ViewStats,
    thresholds_mm: list[float],
) -> dict[str, dict[str, Any]]:
    """Per label name and ``all``: labelled pixels, points, and (with a ground truth) accuracy."""
    names = {lab.name: lab.id for lab in labels.labels if lab.id != 0}
    truth = stats.truth
    distance = SurfaceDistance(truth) if truth is not None else None
    out: dict[str, dict[str, Any]] = {}
    for name, label_id in [*names.items(), (ALL, None)]:
        if name == ALL and len(names) == 1:
            only = next(iter(names))
            out[ALL] = dict(out[only])  # one label: "all" is that label
            continue
        pixels = int(stats.pixels[1:].sum()) if label_id is None else int(stats.pixels[label_id])
        points = measured_points(recon, name)
        row: dict[str, Any] = {"pixels": pixels}
        if name in recon.clouds:
            row["points"] = int(len(points))
        elif name in recon.meshes:
            row["points"] = int(len(recon.meshes[name].vertices))  # the surface's vertices
            row["triangles"] = int(len(recon.meshes[name].triangles))
            row["surface_samples"] = int(len(points))
        else:
            row["points"] = 0
        if truth is not None and distance is not None:
            select = truth.select(label_id)
            precision_d, offsets = distance.measure(points, label_id)
            recall_d = nearest_distances(truth.points[select], points)
            seen = stats.seen[select] if stats.seen is not None else None
            row.update(accuracy(precision_d, recall_d, seen, thresholds_mm))
            if name == ALL or len(names) == 1:
                row["thickness_mm"] = thickness_mm(offsets)
            row["truth_samples"] = int(select.sum())
            row["truth_samples_seen"] = int(seen.sum()) if seen is not None else None
        out[name] = row
    return out
