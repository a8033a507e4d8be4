"""The paper's photogrammetry test with the numbers it never had: COLMAP (pycolmap, on the CPU)
recovers the cameras of a run's RGB views by structure from motion, and agrisim, which knows
where every camera really was, scores them.

Pipeline: SIFT features, at a contrast threshold for rendered views (:data:`PEAK_THRESHOLD`);
by default the robot's kinematic camera centres as pose priors (``priors="robot"``; ``"none"``
is COLMAP from the images alone, as the paper ran it); matching, exhaustive (every pair),
sequential (each view with the next ``overlap`` views of the routine) or spatial (each with its
``overlap`` nearest by prior position); incremental mapping, again with the next seed while the
largest model holds too few views. The intrinsics are
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

import itertools
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
Matcher = Literal["exhaustive", "sequential", "spatial"]
Intrinsics = Literal["known", "estimated"]
Priors = Literal["robot", "none"]
MATCHERS: tuple[str, ...] = ("exhaustive", "sequential", "spatial")
INTRINSICS: tuple[str, ...] = ("known", "estimated")
PRIORS: tuple[str, ...] = ("robot", "none")
#: the stages :func:`run_colmap` reports to its progress callback, in order
STAGES = ("features", "matching", "mapping")
#: views whose centres a robust similarity puts this near the truth (m) fix the alignment
ALIGN_WITHIN = 0.02
#: SIFT's contrast threshold (its peak threshold) for rendered views. COLMAP's own, 0.02 / 3,
#: suits photographs; rendered plants in a plain lab are smoother, and at it the test's 36 views
#: gave 400-970 features each and two or three pairs over the 100 inliers the mapper needs to
#: start a model, so one grey level of noise decided between 18, 2 and 0 views placed. At 0.001:
#: 1,700-2,300 features (median 2,300), 39 such pairs, 34-36 placed (bench/colmap_robustness.py).
PEAK_THRESHOLD = 0.001
#: COLMAP's own SIFT peak threshold (what the paper's COLMAP ran with)
COLMAP_PEAK_THRESHOLD = 0.02 / 3
#: while fewer than this share of the views are placed, the matches are mapped again, next seed
MIN_SHARE = 0.9
#: how far (mm, one standard deviation) the robot's kinematic camera centres are trusted as priors
PRIOR_STD_MM = 10.0
#: with the robot's priors, a verified pair whose relative rotation differs from the kinematics'
#: by more than this (degrees) is dropped before mapping. On the test's 36 views, 118 of the 184
#: pairs within an arm agree within 3 degrees; all but one of the 66 across the arms (views of
#: the plant's far sides, matched on look-alike clutter) disagree by 30 or more, and mapped, they
#: fold one arm's views onto the other's.
PAIR_MAX_TURN_DEG = 5.0


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


def _check(
    matcher: str,
    intrinsics: str,
    overlap: int,
    max_features: int,
    priors: str,
    prior_std_mm: float,
    peak_threshold: float,
    attempts: int,
) -> None:
    if matcher not in MATCHERS:
        raise UserError(f"--matcher {matcher!r} is unknown; allowed: {', '.join(MATCHERS)}")
    if intrinsics not in INTRINSICS:
        raise UserError(f"--intrinsics {intrinsics!r} is unknown; allowed: {', '.join(INTRINSICS)}")
    if priors not in PRIORS:
        raise UserError(f"--priors {priors!r} is unknown; allowed: {', '.join(PRIORS)}")
    if matcher == "spatial" and priors != "robot":
        raise UserError("--matcher spatial pairs views by their prior positions: it needs --priors robot")
    if overlap < 1:
        raise UserError(f"--overlap must be 1 or more (views matched with each), got {overlap}")
    if max_features < 64:
        raise UserError(f"--max-features must be 64 or more, got {max_features}")
    if not (prior_std_mm > 0 and np.isfinite(prior_std_mm)):
        raise UserError(f"--prior-std-mm must be a positive number of millimetres, got {prior_std_mm}")
    if not (0 < peak_threshold < 1):
        raise UserError(f"--peak-threshold must lie between 0 and 1 (COLMAP's own is 0.0067), got {peak_threshold}")
    if attempts < 1:
        raise UserError(f"--attempts must be 1 or more (mappings tried, each with the next seed), got {attempts}")


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
    priors: Priors = "robot",
    prior_std_mm: float = PRIOR_STD_MM,
    overlap: int = 10,
    max_features: int = 8192,
    peak_threshold: float = PEAK_THRESHOLD,
    attempts: int = 3,
    seed: int = 0,
    feature_threads: int = -1,
    overwrite: bool = False,
    progress: Callable[[str, int, int], None] | None = None,
) -> ColmapResult:
    """COLMAP on the RGB views of the complete run in ``run_dir``, scored against the truth, into
    ``run_dir/colmap/`` (an existing one needs ``overwrite`` and is replaced only when the new
    one is complete). ``progress(stage, done, total)`` hears of each stage (:data:`STAGES`) and,
    while mapping, of each view registered.

    ``priors="robot"`` uses what the arms' kinematics say of each view (the run's
    ``cameras.json``): its camera centre as COLMAP's pose prior, trusted to ``prior_std_mm``, so
    that the mapper's bundle adjustment holds every model to them and each comes out in the
    world's frame and metres; and its orientation to check each verified pair, dropping those
    whose relative rotation disagrees (:data:`PAIR_MAX_TURN_DEG`: views of the plant's far sides
    match on look-alike clutter, and such pairs fold one arm's views onto the other's).
    ``priors="none"`` is COLMAP from the images alone, as the paper ran it: the largest model
    kept. ``matcher="spatial"`` pairs each view with its ``overlap`` nearest by prior position.
    Either way, while fewer than :data:`MIN_SHARE` of the views are placed the matches are mapped
    again with the next seed, ``attempts`` times in all, and the best attempt kept.
    ``feature_threads`` SIFT threads (-1: every core); matching and
    mapping run on one thread, so that one machine gives one model of the same features."""
    _check(matcher, intrinsics, overlap, max_features, priors, prior_std_mm, peak_threshold, attempts)
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

    settings = {
        "matcher": matcher,
        "intrinsics": intrinsics,
        "priors": priors,
        "prior_std_mm": prior_std_mm if priors == "robot" else None,
        "overlap": overlap,
        "max_features": max_features,
        "peak_threshold": peak_threshold,
        "attempts": attempts,
        "seed": seed,
    }
    names = [layout.image(run_dir, "rgb", f).name for f in frames]
    rgb = layout.image(run_dir, "rgb", frames[0]).parent
    truth = {f: np.asarray(cameras["frames"][f]["world_T_camera"], float) for f in frames}
    pycolmap.set_random_seed(seed)
    quiet = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = 3  # COLMAP logs every image and pair; the scores say what matters
    with _restored_log_level(pycolmap, quiet), staged_dir(out) as staging:
        database = staging / "database.db"
        tell("features", 0, len(frames))
        extract_features(
            database, rgb, names, np.asarray(cameras["intrinsics"]["K"], float), intrinsics, max_features,
            peak_threshold, feature_threads, cameras["intrinsics"].get("distortion"),
        )  # fmt: skip
        if priors == "robot":
            write_position_priors(
                database, {n: truth[f][:3, 3] for f, n in zip(frames, names, strict=True)}, prior_std_mm
            )
        tell("features", len(frames), len(frames))
        tell("matching", 0, 1)
        rotations = {n: truth[f][:3, :3] for f, n in zip(frames, names, strict=True)} if priors == "robot" else None
        kept, dropped = match_features(database, matcher, overlap, rotations)
        tell("matching", 1, 1)
        sparse = staging / "sparse"
        sparse.mkdir()
        models, tries = map_with_retries(
            database, rgb, sparse, len(frames), intrinsics, priors == "robot", prior_std_mm, seed, attempts,
            lambda done: tell("mapping", done, len(frames)),
        )  # fmt: skip
        database.unlink()  # features and matches: large, and what the model holds is kept
        result = _score(models, frames, names, truth, sparse, settings, seed, out)
        result.attempts = tries
        result.pairs = {"verified": kept, "dropped_by_kinematics": dropped}
        write_json(staging / POSES_JSON, _document(result))
    return result


def colmap_camera(K: np.ndarray, lens: dict[str, Any] | None) -> tuple[str, list[float]]:
    """COLMAP's camera model and parameters for ``K`` and a lens (cameras.json's form):
    ``PINHOLE``; ``OPENCV`` (k1, k2, p1, p2) or ``FULL_OPENCV`` when k3 is set; ``OPENCV_FISHEYE``.
    COLMAP's first pixel centre is (0.5, 0.5), agrisim's (0, 0)."""
    pinhole = [K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5]
    if lens is None:
        return "PINHOLE", pinhole
    if lens["model"] == "fisheye":
        return "OPENCV_FISHEYE", pinhole + [lens[k] for k in ("k1", "k2", "k3", "k4")]
    radial = pinhole + [lens[k] for k in ("k1", "k2", "p1", "p2")]
    return ("OPENCV", radial) if lens["k3"] == 0 else ("FULL_OPENCV", radial + [lens["k3"], 0.0, 0.0, 0.0])


def extract_features(
    database: Path,
    rgb: Path,
    names: list[str],
    K: np.ndarray,
    intrinsics: str,
    max_features: int,
    peak_threshold: float,
    threads: int = -1,
    lens: dict[str, Any] | None = None,
) -> None:
    """SIFT features of ``rgb/names`` into a new COLMAP ``database``: one camera for all views,
    the run's own (``known``: ``K`` and ``lens``, cameras.json's distortion) or COLMAP's to
    estimate (``estimated``)."""
    import pycolmap

    reader = pycolmap.ImageReaderOptions()
    if intrinsics == "known":
        model, params = colmap_camera(K, lens)
        reader.camera_model = model
        reader.camera_params = ",".join(repr(float(x)) for x in params)
    else:
        reader.camera_model = "SIMPLE_RADIAL"
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.num_threads = threads
    extraction.sift.max_num_features = max_features
    extraction.sift.peak_threshold = peak_threshold
    pycolmap.extract_features(
        database,
        rgb,
        image_names=names,
        camera_mode=pycolmap.CameraMode.SINGLE,
        reader_options=reader,
        extraction_options=extraction,
        device=pycolmap.Device.cpu,
    )


def write_position_priors(database: Path, centres: dict[str, np.ndarray], std_mm: float) -> None:
    """Each view's camera centre (world, metres), by image name, as a COLMAP pose prior with an
    isotropic covariance of ``std_mm``."""
    import pycolmap

    db = pycolmap.Database.open(database)
    try:
        for image in db.read_all_images():
            prior = pycolmap.PosePrior()
            camera = pycolmap.sensor_t(type=pycolmap.SensorType.CAMERA, id=image.camera_id)
            prior.corr_data_id = pycolmap.data_t(sensor_id=camera, id=image.image_id)
            prior.position = np.asarray(centres[image.name], float)
            prior.position_covariance = np.eye(3) * (std_mm * 1e-3) ** 2
            prior.coordinate_system = pycolmap.PosePriorCoordinateSystem.CARTESIAN
            db.write_pose_prior(prior)
    finally:
        db.close()


def match_features(
    database: Path, matcher: str, overlap: int, rotations: dict[str, np.ndarray] | None = None
) -> tuple[int, int]:
    """Match and verify the views' features: every pair, each with the next ``overlap`` of the
    routine, or each with its ``overlap`` nearest by prior position (``spatial``). Given the
    views' kinematic orientations (``rotations``: world_R_camera by image name), every verified
    pair whose relative rotation disagrees with theirs by more than :data:`PAIR_MAX_TURN_DEG` is
    dropped. Returns the verified pairs (of 15 inliers or more) kept and dropped."""
    import pycolmap

    matching = pycolmap.FeatureMatchingOptions()
    # One thread: COLMAP's verification gives other matches from one run to the next when
    # threaded; on one the same features and seed give the same matches.
    matching.num_threads = 1
    verification = pycolmap.TwoViewGeometryOptions()
    verification.compute_relative_pose = rotations is not None
    kw: dict[str, Any] = {"matching_options": matching, "verification_options": verification}
    if matcher == "exhaustive":
        pycolmap.match_exhaustive(database, **kw, device=pycolmap.Device.cpu)
    elif matcher == "sequential":
        pairing = pycolmap.SequentialPairingOptions()
        pairing.overlap = overlap
        pycolmap.match_sequential(database, **kw, pairing_options=pairing, device=pycolmap.Device.cpu)
    else:
        spatial = pycolmap.SpatialPairingOptions()
        spatial.max_num_neighbors = overlap
        spatial.ignore_z = False  # the hemisphere's views differ in height as much as around it
        pycolmap.match_spatial(database, **kw, pairing_options=spatial, device=pycolmap.Device.cpu)
    return _verify_against_kinematics(database, rotations)


def _verify_against_kinematics(database: Path, rotations: dict[str, np.ndarray] | None) -> tuple[int, int]:
    """Drop the verified pairs whose relative rotation disagrees with the kinematics' (none
    without ``rotations``); the pairs of 15 inliers or more kept and dropped."""
    import pycolmap

    db = pycolmap.Database.open(database)
    try:
        names = {image.image_id: image.name for image in db.read_all_images()}
        kept = dropped = 0
        pair_ids, geometries = db.read_two_view_geometries()
        for pair_id, geometry in zip(pair_ids, geometries, strict=True):
            if len(geometry.inlier_matches) < 15:  # (COLMAP's own least: the mapper ignores the rest)
                continue
            first, second = pycolmap.pair_id_to_image_pair(pair_id)
            if rotations is not None:
                relative = geometry.cam2_from_cam1
                # cam2_from_cam1's rotation, as the kinematics have it: R2^T R1
                truth = rotations[names[second]].T @ rotations[names[first]]
                turn = 180.0 if relative is None else _angle_deg(truth, np.asarray(relative.rotation.matrix()))
                if turn > PAIR_MAX_TURN_DEG:
                    db.delete_two_view_geometry(first, second)
                    dropped += 1
                    continue
            kept += 1
    finally:
        db.close()
    return kept, dropped


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle (degrees) of the rotation between rotation matrices ``a`` and ``b``."""
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0))))


def map_with_retries(
    database: Path,
    rgb: Path,
    sparse: Path,
    views: int,
    intrinsics: str,
    use_priors: bool,
    prior_std_mm: float,
    seed: int,
    attempts: int,
    registered: Callable[[int], None] | None = None,
) -> tuple[dict[int, Any], list[dict[str, int]]]:
    """Incremental mapping of the matched ``database``, again with the next seed while the
    views placed (with priors: in every model; without: in the largest) are fewer than
    :data:`MIN_SHARE` of the ``views``: the models of the best
    attempt, and each attempt's seed and views placed. ``registered(n)`` hears of each view
    placed."""
    import pycolmap

    best: dict[int, Any] = {}
    best_k = 0
    tries: list[dict[str, int]] = []
    for k in range(attempts):
        options = pycolmap.IncrementalPipelineOptions()
        # One thread: threaded, the mapper gave other models of the same matches from one run to
        # the next (2 or 18 of 36 views, measured).
        options.num_threads = 1
        options.random_seed = seed + k
        if intrinsics == "known":  # a calibrated camera: held as given
            options.ba_refine_focal_length = False
            options.ba_refine_principal_point = False
            options.ba_refine_extra_params = False
        if use_priors:
            options.use_prior_position = True
            # a view whose kinematics disagree with its images is down-weighted, not trusted
            options.use_robust_loss_on_prior_position = True
        count = itertools.count(1)

        def next_image(count: Iterator[int] = count) -> None:
            done = next(count)
            if registered is not None:
                registered(done)

        folder = sparse / f"attempt-{k}"
        folder.mkdir()
        models = pycolmap.incremental_mapping(database, rgb, folder, options=options, next_image_callback=next_image)
        shutil.rmtree(folder)  # the mapper wrote each model; the kept one is written by _score
        sizes = [m.num_reg_images() for m in models.values()]
        # with priors every model is kept (each in the world's frame); from the images, the largest
        placed = sum(sizes) if use_priors else max(sizes, default=0)
        tries.append({"seed": seed + k, "registered": placed})
        if placed > (tries[best_k]["registered"] if best else -1):
            best, best_k = models, k
        if placed >= MIN_SHARE * views:
            break
    return best, tries


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
            rotation_error_deg=_angle_deg(truth[frame][:3, :3], turn @ model_R_cam),
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


def _document(result: ColmapResult) -> dict[str, Any]:
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
