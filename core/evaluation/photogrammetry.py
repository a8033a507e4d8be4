"""The paper's photogrammetry test with the numbers it never had: COLMAP (pycolmap, on the CPU)
recovers the cameras of a run's RGB views by structure from motion, and agrisim, which knows
where every camera really was, scores them.

Pipeline: SIFT features; matching, exhaustive (every pair) or sequential (each view with the
next ``overlap`` views of the routine, for long runs); incremental mapping. The intrinsics are
either the run's own (``known``: a calibrated camera, held fixed) or estimated by COLMAP from a
guess (``estimated``: a simple radial camera, as an uncalibrated capture). The largest model is
then aligned to the truth by the similarity (scale, rotation, translation) that best maps its
camera centres onto the true ones (least squares, Umeyama's, over the views that pycolmap's
robust similarity places within 2 cm, so that a few misplaced views cannot drag the others off:
the poses a reconstruction on COLMAP's cameras gets, ``recon.poses = "colmap"``), its
orientations by the one
rotation that best maps them onto the true ones (their chordal mean: the centres' similarity
cannot fix the turn about the line of centres of views along one arc), and each view is scored:
its centre's distance from the truth (mm), the angle between its aligned rotation and the true
one (degrees), and the mean reprojection error of its observations (pixels).

``RUN/colmap/`` holds ``sparse/0/`` (COLMAP's binary model: cameras, images and points; the
images named as ``rgb/``'s files) and ``poses.json`` (the scores). COLMAP's conventions: image
coordinates with the first pixel's centre at (0.5, 0.5), so the run's principal point (pixel
centres at integers) is shifted by half a pixel; cameras as OpenCV's (x right, y down, z
forward), so rotations compare directly.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.files.atomic import staged_dir, write_json
from agrisim.files.rundir import read_run

COLMAP_DIR = layout.COLMAP
POSES_JSON = "poses.json"
Matcher = Literal["exhaustive", "sequential"]
Intrinsics = Literal["known", "estimated"]
MATCHERS: tuple[str, ...] = ("exhaustive", "sequential")
INTRINSICS: tuple[str, ...] = ("known", "estimated")
#: the stages :func:`run_colmap` reports to its progress callback, in order
STAGES = ("features", "matching", "mapping")
#: views whose centres a robust similarity puts this near the truth (m) fix the alignment
ALIGN_WITHIN = 0.02


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
    """What :func:`run_colmap` found and wrote."""

    out: Path
    views: list[ViewScore]
    models: int
    scale: float | None  # metres per COLMAP unit (the alignment's scale)
    reprojection_px: float | None  # mean over every observation of the model
    points: int
    settings: dict[str, Any] = field(default_factory=dict)

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
        }
        for name in ("centre_error_mm", "rotation_error_deg"):
            values = [getattr(v, name) for v in self.views if getattr(v, name) is not None]
            doc[f"median_{name}"] = float(np.median(values)) if values else None
            doc[f"max_{name}"] = float(np.max(values)) if values else None
        return doc


def _check(matcher: str, intrinsics: str, overlap: int, max_features: int) -> None:
    if matcher not in MATCHERS:
        raise UserError(f"--matcher {matcher!r} is unknown; allowed: {', '.join(MATCHERS)}")
    if intrinsics not in INTRINSICS:
        raise UserError(f"--intrinsics {intrinsics!r} is unknown; allowed: {', '.join(INTRINSICS)}")
    if overlap < 1:
        raise UserError(f"--overlap must be 1 or more (views matched with each), got {overlap}")
    if max_features < 64:
        raise UserError(f"--max-features must be 64 or more, got {max_features}")


def _frames_in_routine_order(run: dict[str, Any], frames: list[str]) -> list[str]:
    """The complete frames in the order the routine took them (for sequential matching each arm's
    setpoints follow one another; the arms are not interleaved)."""
    rows = [(r.get("robot", ""), int(r.get("index", 0)), r.get("frame")) for r in run.get("results") or []]
    order = {frame: k for k, (_, _, frame) in enumerate(sorted(rows)) if frame}
    return sorted(frames, key=lambda f: (order.get(f, len(order)), f))


def run_colmap(
    run_dir: Path,
    *,
    matcher: Matcher = "exhaustive",
    intrinsics: Intrinsics = "known",
    overlap: int = 10,
    max_features: int = 8192,
    seed: int = 0,
    overwrite: bool = False,
    progress: Callable[[str, int, int], None] | None = None,
) -> ColmapResult:
    """COLMAP on the RGB views of the complete run in ``run_dir``, scored against the truth, into
    ``run_dir/colmap/`` (an existing one needs ``overwrite`` and is replaced only when the new
    one is complete). ``progress(stage, done, total)`` hears of each stage (:data:`STAGES`) and,
    while mapping, of each view registered."""
    _check(matcher, intrinsics, overlap, max_features)
    run_dir = Path(run_dir)
    run, cameras = read_run(run_dir)
    frames = _frames_in_routine_order(run, sorted(run.get("frames_complete") or []))
    if len(frames) < 2:
        raise UserError(f"the run in {run_dir} has {len(frames)} frame(s): structure from motion needs 2 or more")
    out = run_dir / COLMAP_DIR
    if out.exists() and not overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")
    import pycolmap

    def tell(stage: str, done: int, total: int) -> None:
        if progress is not None:
            progress(stage, done, total)

    intr = cameras["intrinsics"]
    K = np.asarray(intr["K"], float)
    settings = {"matcher": matcher, "intrinsics": intrinsics, "overlap": overlap, "max_features": max_features}
    names = [layout.image(run_dir, "rgb", f).name for f in frames]
    rgb = layout.image(run_dir, "rgb", frames[0]).parent
    pycolmap.set_random_seed(seed)
    quiet = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = 3  # COLMAP logs every image and pair; the scores say what matters
    with _restored_log_level(pycolmap, quiet), staged_dir(out) as staging:
        database = staging / "database.db"
        reader = pycolmap.ImageReaderOptions()
        if intrinsics == "known":
            reader.camera_model = "PINHOLE"
            # COLMAP's first pixel centre is (0.5, 0.5); agrisim's is (0, 0)
            reader.camera_params = ",".join(repr(float(x)) for x in (K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5))
        else:
            reader.camera_model = "SIMPLE_RADIAL"
        extraction = pycolmap.FeatureExtractionOptions()
        extraction.num_threads = 1
        extraction.sift.max_num_features = max_features
        tell("features", 0, len(frames))
        pycolmap.extract_features(
            database,
            rgb,
            image_names=names,
            camera_mode=pycolmap.CameraMode.SINGLE,
            reader_options=reader,
            extraction_options=extraction,
            device=pycolmap.Device.cpu,
        )
        tell("features", len(frames), len(frames))
        matching = pycolmap.FeatureMatchingOptions()
        # One thread from here on: COLMAP's verification and mapping give other models from
        # one run to the next when threaded (2 or 18 of 36 views registered, measured); the
        # same views and seed then give the same model.
        matching.num_threads = 1
        tell("matching", 0, 1)
        if matcher == "exhaustive":
            pycolmap.match_exhaustive(database, matching_options=matching, device=pycolmap.Device.cpu)
        else:
            pairing = pycolmap.SequentialPairingOptions()
            pairing.overlap = overlap
            pycolmap.match_sequential(
                database, matching_options=matching, pairing_options=pairing, device=pycolmap.Device.cpu
            )
        tell("matching", 1, 1)
        options = pycolmap.IncrementalPipelineOptions()
        options.num_threads = 1
        options.random_seed = seed
        if intrinsics == "known":  # a calibrated camera: held as given
            options.ba_refine_focal_length = False
            options.ba_refine_principal_point = False
            options.ba_refine_extra_params = False
        registered = [0]

        def next_image() -> None:
            registered[0] += 1
            tell("mapping", registered[0], len(frames))

        tell("mapping", 0, len(frames))
        sparse = staging / "sparse"
        sparse.mkdir()
        models = pycolmap.incremental_mapping(database, rgb, sparse, options=options, next_image_callback=next_image)
        database.unlink()  # features and matches: large, and what the model holds is kept
        for folder in sparse.iterdir():  # the mapper wrote each model; the largest is kept
            shutil.rmtree(folder)
        result = _score(models, frames, names, cameras, sparse, settings, seed, out)
        write_json(staging / POSES_JSON, _document(result))
    return result


@contextmanager
def _restored_log_level(pycolmap: Any, level: int) -> Iterator[None]:
    try:
        yield
    finally:
        pycolmap.logging.minloglevel = level


def _score(
    models: dict[int, Any],
    frames: list[str],
    names: list[str],
    cameras: dict[str, Any],
    sparse: Path,
    settings: dict[str, Any],
    seed: int,
    out: Path,
) -> ColmapResult:
    """Write the largest model as ``sparse/0`` and score its views against the truth."""
    from scipy.spatial.transform import Rotation  # (here: the GPU machine reads estimated_poses without SciPy)

    if not models:
        return ColmapResult(out, [ViewScore(f, False) for f in frames], 0, None, None, 0, settings)
    model = max(models.values(), key=lambda m: (m.num_reg_images(), m.num_points3D()))
    (sparse / "0").mkdir()
    model.write(sparse / "0")
    by_name = {img.name: img for img in model.images.values() if img.has_pose}
    found = [(f, by_name[n]) for f, n in zip(frames, names, strict=True) if n in by_name]
    truth = {f: np.asarray(cameras["frames"][f]["world_T_camera"], float) for f in frames}
    scale = None
    scores = {f: ViewScore(f, False) for f in frames}
    if len(found) >= 3:
        centres = np.array([img.projection_center() for _, img in found])
        true_centres = np.array([truth[f][:3, 3] for f, _ in found])
        inliers = _aligned_views(centres, true_centres, seed)
        s, R, t = _similarity(centres[inliers], true_centres[inliers])
        scale = s
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
            cos = (np.trace(truth[frame][:3, :3].T @ turn @ model_R_cam) - 1.0) / 2.0
            # the pose a reconstruction gets: the whole model moved by the one similarity
            estimate = np.eye(4)
            estimate[:3, :3], estimate[:3, 3] = R @ model_R_cam, s * R @ c + t
            scores[frame] = ViewScore(
                frame,
                True,
                centre_error_mm=float(np.linalg.norm(estimate[:3, 3] - truth[frame][:3, 3]) * 1e3),
                rotation_error_deg=float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))),
                reprojection_px=_reprojection(model, img),
                world_T_camera=estimate,
            )
    else:  # too few to align: registered, unscored
        for frame, img in found:
            scores[frame] = ViewScore(frame, True, reprojection_px=_reprojection(model, img))
    error = float(model.compute_mean_reprojection_error()) if model.num_points3D() else None
    return ColmapResult(
        out, [scores[f] for f in frames], len(models), scale, error, int(model.num_points3D()), settings
    )


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


def _document(result: ColmapResult) -> dict[str, Any]:
    import pycolmap

    return {
        "colmap": {"pycolmap": pycolmap.__version__, **result.settings},
        "summary": result.summary(),
        "alignment": (
            "a similarity (Umeyama) of the model's camera centres onto the true ones, fitted to the views a robust "
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


def estimated_poses(run_dir: Path) -> dict[str, np.ndarray]:
    """COLMAP's camera poses of the run's views, in the world (OpenCV cameras, metres), by
    frame; only the views it registered and scored. Refused without ``agrisim colmap RUN``."""
    path = Path(run_dir) / COLMAP_DIR / POSES_JSON
    if not path.is_file():
        raise UserError(f"{path} does not exist: recon.poses = 'colmap' needs agrisim colmap {run_dir} first")
    try:
        views = json.loads(path.read_text())["views"]
        poses = {v["frame"]: np.asarray(v["world_T_camera"], float) for v in views if v.get("world_T_camera")}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise UserError(f"cannot read {path}: {exc}") from None
    if not poses:
        raise UserError(f"{path}: COLMAP placed none of the views; there is nothing to reconstruct from")
    return poses
