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
from pathlib import Path
from typing import Any, Literal

import numpy as np

from agrisim.errors import OutputError, UserError
from agrisim.files import layout
from agrisim.files.atomic import staged_dir, write_json
from agrisim.files.rundir import read_run
from agrisim.plugins.poses.colmap.scoring import ColmapResult, angle_deg, document, score

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
#: SIFT's contrast threshold (its peak threshold) for rendered views. COLMAP's own, 0.02 / 3,
#: suits photographs; rendered plants in a plain lab are smoother, and at it 36 views of the test's
#: plant (its views until 2026-11-29: 3x6 an arm, 16 degrees apart, 960x540)
#: gave 400-970 features each and two or three pairs over the 100 inliers the mapper needs to
#: start a model, so one grey level of noise decided between 18, 2 and 0 views placed. At 0.001:
#: 1,700-2,300 features (median 2,300), 39 such pairs, 34-36 placed (bench/colmap_robustness.py
#: --setpoints 3x6 --theta 50 130 --phi 40 70).
PEAK_THRESHOLD = 0.001
#: COLMAP's own SIFT peak threshold (what the paper's COLMAP ran with)
COLMAP_PEAK_THRESHOLD = 0.02 / 3
#: while fewer than this share of the views are placed, the matches are mapped again, next seed
MIN_SHARE = 0.9
#: how far (mm, one standard deviation) the robot's kinematic camera centres are trusted as priors
PRIOR_STD_MM = 10.0
#: with the robot's priors, a verified pair whose relative rotation differs from the kinematics'
#: by more than this (degrees) is dropped before mapping. On those 36 views, 118 of the 184
#: pairs within an arm agree within 3 degrees; all but one of the 66 across the arms (views of
#: the plant's far sides, matched on look-alike clutter) disagree by 30 or more, and mapped, they
#: fold one arm's views onto the other's.
PAIR_MAX_TURN_DEG = 5.0


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
        result = score(models, frames, names, truth, sparse, settings, seed, out)
        result.attempts = tries
        result.pairs = {"verified": kept, "dropped_by_kinematics": dropped}
        write_json(staging / POSES_JSON, document(result))
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
                turn = 180.0 if relative is None else angle_deg(truth, np.asarray(relative.rotation.matrix()))
                if turn > PAIR_MAX_TURN_DEG:
                    db.delete_two_view_geometry(first, second)
                    dropped += 1
                    continue
            kept += 1
    finally:
        db.close()
    return kept, dropped


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
        shutil.rmtree(folder)  # the mapper wrote each model; the kept one is written by score
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
