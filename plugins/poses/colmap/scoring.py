"""COLMAP's cameras scored against the truth: its models aligned to the world by a robust
similarity of the camera centres (pycolmap's LO-RANSAC), then each view's centre, rotation and
reprojection errors (:class:`ViewScore`), the whole reconstruction's figures
(:class:`ColmapResult`) and ``poses.json`` (:func:`document`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.errors import UserError

#: views whose centres a robust similarity puts this near the truth (m) fix the alignment
ALIGN_WITHIN = 0.02


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle (degrees) of the rotation between rotation matrices ``a`` and ``b``."""
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0))))


@dataclass
class ViewScore:
    """One view against the truth; the errors are None for a view COLMAP did not register."""

    frame: str
    registered: bool
    centre_error_mm: float | None = None
    rotation_error_deg: float | None = None
    reprojection_px: float | None = None
    world_T_camera: np.ndarray | None = None  # COLMAP's pose moved into the world by the similarity


@dataclass
class ColmapResult:
    """What :func:`~agrisim.plugins.poses.colmap.photogrammetry.run_colmap` found and wrote."""

    out: Path
    views: list[ViewScore]
    models: int
    scale: float | None  # metres per COLMAP unit (the alignment's scale)
    reprojection_px: float | None  # mean over every observation of the model
    points: int
    settings: dict[str, Any] = field(default_factory=dict)
    attempts: list[dict[str, int]] = field(default_factory=list)  # each mapping's seed and views placed
    pairs: dict[str, int] = field(default_factory=dict)  # verified pairs kept, and dropped by the kinematics

    @property
    def registered(self) -> int:
        return sum(v.registered for v in self.views)

    def summary(self) -> dict[str, Any]:
        """The run's figures: registered views, medians and maxima of the errors."""
        doc: dict[str, Any] = {
            "views": len(self.views),
            "registered": self.registered,
            "within_20mm": sum(
                v.centre_error_mm is not None and v.centre_error_mm <= ALIGN_WITHIN * 1e3 for v in self.views
            ),
            "models": self.models,
            "points": self.points,
            "scale_m_per_unit": self.scale,
            "reprojection_px": self.reprojection_px,
            "attempts": self.attempts,
            "pairs": self.pairs,
        }
        for name in ("centre_error_mm", "rotation_error_deg"):
            values = [getattr(v, name) for v in self.views if getattr(v, name) is not None]
            doc[f"median_{name}"] = float(np.median(values)) if values else None
            doc[f"max_{name}"] = float(np.max(values)) if values else None
        return doc


def score(
    models: dict[int, Any],
    frames: list[str],
    names: list[str],
    truth: dict[str, np.ndarray],
    sparse: Path,
    settings: dict[str, Any],
    seed: int,
    out: Path,
) -> ColmapResult:
    """Write the models as ``sparse/0``, ``sparse/1``... (the largest first) and score their
    views against the truth. From the images alone only the largest is kept: COLMAP's models
    then share no frame. With the robot's priors every model is held to them, in the world's
    frame, so each is kept: the kinematics join what the images could not."""
    if not models:
        return ColmapResult(out, [ViewScore(f, False) for f in frames], 0, None, None, 0, settings)
    ranked = sorted(models.values(), key=lambda m: (m.num_reg_images(), m.num_points3D()), reverse=True)
    kept = ranked if settings["priors"] == "robot" else ranked[:1]
    scores = {f: ViewScore(f, False) for f in frames}
    scales: list[float | None] = []
    for k, model in enumerate(kept):
        (sparse / str(k)).mkdir()
        model.write(sparse / str(k))
        scales.append(_score_model(model, frames, names, truth, seed, scores))
    observations = [m.compute_num_observations() for m in kept]
    error = (
        float(
            sum(m.compute_mean_reprojection_error() * n for m, n in zip(kept, observations, strict=True))
            / sum(observations)
        )
        if sum(observations)
        else None
    )
    points = sum(int(m.num_points3D()) for m in kept)
    return ColmapResult(out, [scores[f] for f in frames], len(models), scales[0], error, points, settings)


def _score_model(
    model: Any,
    frames: list[str],
    names: list[str],
    truth: dict[str, np.ndarray],
    seed: int,
    scores: dict[str, ViewScore],
) -> float | None:
    """Score the views of one model into ``scores`` (but those a larger model scored), aligned to
    the truth by the model's own similarity; its scale (metres per model unit), None when too few
    views to align."""
    from scipy.spatial.transform import Rotation  # (here: the GPU machine reads estimated_poses without SciPy)

    by_name = {img.name: img for img in model.images.values() if img.has_pose}
    found = [(f, by_name[n]) for f, n in zip(frames, names, strict=True) if n in by_name]
    if len(found) < 3:  # too few to align: registered, unscored
        for frame, img in found:
            if not scores[frame].registered:
                scores[frame] = ViewScore(frame, True, reprojection_px=_reprojection(model, img))
        return None
    centres = np.array([img.projection_center() for _, img in found])
    true_centres = np.array([truth[f][:3, 3] for f, _ in found])
    inliers = _aligned_views(centres, true_centres, seed)
    s, R, t = _similarity(centres[inliers], true_centres[inliers])
    model_R_cams = [np.asarray(img.cam_from_world().rotation.matrix()).T for _, img in found]
    # orientations aligned on their own: the centres' similarity leaves its turn about the
    # line of centres ill-determined when the views lie near one arc. The rotation A that
    # minimises sum |world_i - A model_i|^2 is the chordal mean of world_i model_i^T.
    turn = (
        Rotation.from_matrix(
            [truth[f][:3, :3] @ m.T for (f, _), m, keep in zip(found, model_R_cams, inliers, strict=True) if keep]
        )
        .mean()
        .as_matrix()
    )
    for (frame, img), c, model_R_cam in zip(found, centres, model_R_cams, strict=True):
        if scores[frame].registered:  # also in a larger model (models may share views): scored there
            continue
        # the pose a reconstruction gets: the whole model moved by the one similarity
        estimate = np.eye(4)
        estimate[:3, :3], estimate[:3, 3] = R @ model_R_cam, s * R @ c + t
        scores[frame] = ViewScore(
            frame,
            True,
            centre_error_mm=float(np.linalg.norm(estimate[:3, 3] - truth[frame][:3, 3]) * 1e3),
            rotation_error_deg=angle_deg(truth[frame][:3, :3], turn @ model_R_cam),
            reprojection_px=_reprojection(model, img),
            world_T_camera=estimate,
        )
    return s


def _aligned_views(centres: np.ndarray, truth: np.ndarray, seed: int) -> np.ndarray:
    """Which views the alignment is fitted to: those within :data:`ALIGN_WITHIN` of the truth
    under pycolmap's robust similarity (LO-RANSAC), so that a few misplaced views do not drag
    the well-placed ones off; all of them when fewer than three would be left."""
    import pycolmap

    ransac = pycolmap.RANSACOptions()
    ransac.max_error = ALIGN_WITHIN
    ransac.random_seed = seed
    found: Any = pycolmap.estimate_sim3d_robust(centres, truth, ransac)  # (a dict, whatever its stub says)
    if not found:
        return np.ones(len(centres), bool)
    keep = np.array(found["inlier_mask"], dtype=np.bool_)
    return keep if keep.sum() >= 3 else np.ones(len(centres), bool)


def _similarity(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R, t) minimising sum |s R src + t - dst|^2 (Umeyama 1991, pycolmap's estimate)."""
    import pycolmap

    sim = pycolmap.estimate_sim3d(src, dst)
    if sim is None:  # (degenerate centres: all in one point)
        raise UserError("COLMAP's registered cameras all lie in one point: they cannot be aligned to the truth")
    return float(sim.scale), np.asarray(sim.rotation.matrix()), np.asarray(sim.translation)


def _reprojection(model: Any, image: Any) -> float | None:
    """Mean distance (px) between the image's observations and its points projected."""
    pts = [p for p in image.points2D if p.has_point3D()]
    if not pts:
        return None
    xy = np.array([p.xy for p in pts])
    xyz = np.array([model.points3D[p.point3D_id].xyz for p in pts])
    cam = image.cam_from_world()
    in_cam = xyz @ np.asarray(cam.rotation.matrix()).T + np.asarray(cam.translation)
    projected = np.asarray(image.camera.img_from_cam(in_cam))
    return float(np.linalg.norm(projected - xy, axis=1).mean())


def document(result: ColmapResult) -> dict[str, Any]:
    import pycolmap

    return {
        "colmap": {"pycolmap": pycolmap.__version__, **result.settings},
        "summary": result.summary(),
        "alignment": (
            "a similarity (Umeyama) of each kept model's camera centres onto the true ones, fitted to the views a robust "
            f"similarity places within {ALIGN_WITHIN * 1e3:.0f} mm; orientations scored after their chordal mean"
        ),
        "views": [
            {
                "frame": v.frame,
                "registered": v.registered,
                "centre_error_mm": v.centre_error_mm,
                "rotation_error_deg": v.rotation_error_deg,
                "reprojection_px": v.reprojection_px,
                "world_T_camera": None if v.world_T_camera is None else v.world_T_camera.tolist(),
            }
            for v in result.views
        ],
    }
