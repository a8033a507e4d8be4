"""The ``nerfstudio`` exporter: ``RUN_DIR/transforms.json`` plus ``RUN_DIR/masks/<frame>.png``,
readable by nerfstudio's ``nerfstudio-data`` parser (``ns-train nerfacto --data RUN_DIR``;
``depth-nerfacto`` uses the depth). Every run with rendered frames writes it itself at its end
(:data:`agrisim.plugins.sinks.dataset.writer.RUN_EXPORTS`); ``agrisim export nerfstudio RUN_DIR`` writes it again.

- Poses: ``transform_matrix`` is camera-to-world in the OpenGL/Blender convention nerfstudio uses
  (x right, y up, z back: the camera looks along -z), i.e. our OpenCV ``world_T_camera`` with
  its y and z axes negated. The world frame is agrisim's (metres, z up), as nerfstudio expects.
- Intrinsics: one shared camera, ``camera_model`` ``OPENCV`` with the lens's k1, k2, k3, p1, p2
  (0 for a pinhole), or ``OPENCV_FISHEYE`` with k1..k4 for a fisheye lens. nerfstudio
  puts pixel centres at +0.5 (pixel (i, j) spans [i, i+1)), agrisim at integer coordinates, so
  ``cx`` and ``cy`` are ours + 0.5; ``fl_x``, ``fl_y``, ``w``, ``h`` are unchanged.
- ``file_path`` is ``rgb/<frame>.png``, ``depth_file_path`` ``depth/<frame>.png`` (uint16
  millimetres, 0 = no hit, which nerfstudio's depth losses skip): ``depth_unit_scale_factor``
  0.001 is nerfstudio's default and is written for readers that take it from the file. A run
  that keeps its depth as EXR only (``--depth-format exr``) gets no ``depth_file_path``.
- ``mask_path`` is ``masks/<frame>.png``: single-channel uint8, 255 where any plant label is
  (label id != 0), 0 elsewhere. nerfstudio trains only on nonzero mask pixels, so a NeRF of this
  export models the plant, not the lab; drop ``mask_path`` to train on the whole image.
- A bench (``run.json``'s ``bench``): ``masks/`` stay what nerfstudio reads (255 on every
  plant: nerfstudio takes a mask as nonzero or not, so ids in it would change nothing it does),
  and each frame adds ``plant_mask_path``, the run's own ``plants/<frame>.png`` (uint16, the id of
  the plant each pixel shows, 0 none), with the top-level ``plants`` naming each id (name, what
  grew it, seed, x, y: :mod:`agrisim.plugins.sinks.dataset.bench`). nerfstudio's parser ignores
  keys it does not know; a mask of one plant (to train on it alone) is ``plants == id``. A run of
  one plant has neither key.
- Only frames listed in ``run.json``'s ``frames_complete`` are exported, in name order.

Bad input (not a run directory, missing ``run.json``/``cameras.json``/frame images, a run still
marked ``running``) raises :class:`ExportError` before anything is written. The files name the
run's images relative to themselves, so they go into the run directory: an ``OUT`` elsewhere is
refused. They are a pure function of the run's files, so an earlier export is rewritten (with
the same bytes) without ``--overwrite``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np
from PIL import Image

from agrisim import BackendSpec, hookimpl
from agrisim.errors import UserError
from agrisim.files import layout
from agrisim.files.atomic import write_bytes, write_json
from agrisim.files.png import encode_png
from agrisim.files.rundir import read_json
from agrisim.interfaces import ALL, Exporter
from agrisim.plugins.sinks.dataset.bench import bench_rows, read_bench

#: OpenCV optical frame -> OpenGL camera frame (negate y and z), as a right factor on camera-to-world
CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])


class ExportError(UserError):
    """The directory cannot be exported: not a run, or a run missing files (one-line message)."""


def opencv_to_opengl(world_T_camera: np.ndarray) -> np.ndarray:
    """Camera-to-world in OpenGL convention from an OpenCV optical ``world_T_camera`` (4 x 4)."""
    return np.asarray(world_T_camera, np.float64) @ CV_TO_GL


def nerfstudio_transforms(
    intrinsics: dict[str, Any],
    frames: dict[str, dict[str, Any]],
    depth_png: bool = True,
    bench: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The ``transforms.json`` document for ``frames`` (name -> cameras.json frame entry).

    ``intrinsics`` is cameras.json's: ``K`` (pixel centres at integers), ``width``, ``height``.
    Paths are relative to the run directory, where transforms.json lives; ``depth_png``: the
    frames have millimetre depth PNGs to name (not an EXR-only run); ``bench``: the rows of a
    bench's plants (each frame then names its ``plant_mask_path``).
    """
    K = np.asarray(intrinsics["K"], np.float64)
    lens = intrinsics.get("distortion") or {"model": "brown-conrady"}
    if lens["model"] == "fisheye":
        distortion = {"camera_model": "OPENCV_FISHEYE", **{k: float(lens[k]) for k in ("k1", "k2", "k3", "k4")}}
    else:  # OPENCV: nerfstudio's k3 multiplies r^6 as OpenCV's does
        distortion = {"camera_model": "OPENCV", **{k: float(lens.get(k, 0.0)) for k in ("k1", "k2", "k3", "p1", "p2")}}
    return {
        "camera_model": distortion.pop("camera_model"),
        "fl_x": float(K[0, 0]),
        "fl_y": float(K[1, 1]),
        "cx": float(K[0, 2]) + 0.5,  # nerfstudio: pixel centres at +0.5
        "cy": float(K[1, 2]) + 0.5,
        "w": int(intrinsics["width"]),
        "h": int(intrinsics["height"]),
        **distortion,
        "depth_unit_scale_factor": 0.001,
        "frames": [
            {
                "file_path": f"rgb/{name}.png",
                "transform_matrix": np.round(opencv_to_opengl(frames[name]["world_T_camera"]), 12).tolist(),
                "mask_path": f"masks/{name}.png",
                **({"depth_file_path": f"depth/{name}.png"} if depth_png else {}),
                **({"plant_mask_path": f"{layout.PLANTS}/{name}.png"} if bench else {}),
            }
            for name in sorted(frames)
        ],
        **({"plants": bench} if bench else {}),
    }


def _read_json(path: Path, what: str) -> dict[str, Any]:
    return read_json(path, what, ExportError)


def _valid_intrinsics(intrinsics: Any) -> TypeGuard[dict[str, Any]]:
    """cameras.json's intrinsics: a finite 3 x 3 ``K`` and positive integer ``width``, ``height``."""
    if not isinstance(intrinsics, dict) or not {"K", "width", "height"} <= set(intrinsics):
        return False
    try:
        K = np.asarray(intrinsics["K"], np.float64)
    except (TypeError, ValueError):
        return False
    sizes = (intrinsics["width"], intrinsics["height"])
    return K.shape == (3, 3) and bool(np.isfinite(K).all()) and all(type(n) is int and n > 0 for n in sizes)


def _mask_png(path: Path, width: int, height: int) -> bytes:
    """PNG bytes of the plant mask (255 where label != 0) of the label image at ``path``."""
    try:
        with Image.open(path) as im:
            labels = np.asarray(im)
    except (OSError, ValueError) as exc:
        raise ExportError(f"cannot read {path}: {exc}") from None
    if labels.shape != (height, width):
        raise ExportError(f"{path} is {labels.shape[::-1]} pixels, expected a {width}x{height} label image")
    return encode_png(np.where(labels != 0, 255, 0).astype(np.uint8))


def write_nerfstudio(run_dir: Path) -> Path:
    """Write ``run_dir/transforms.json`` and ``run_dir/masks/`` for the run's complete frames.

    Everything is read and checked first, then the masks and finally transforms.json are written,
    each atomically; bad input raises :class:`ExportError` with nothing written. A run whose
    run.json still says ``running`` is refused (it is being written, or was killed: resume it).
    Returns the path of transforms.json.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ExportError(f"{run_dir} is not a directory: give an agrisim run directory (agrisim run --out DIR)")
    run = _read_json(run_dir / layout.RUN_JSON, "not an agrisim run directory")
    status = run.get("status")
    if status == "running":
        raise ExportError(
            f"the run in {run_dir} is unfinished (status running): let it finish, or continue it with "
            f"agrisim run --resume --out {run_dir}"
        )
    if ((run.get("config") or {}).get("renderer") or {}).get("backend") == "none":
        raise ExportError(f"the run in {run_dir} rendered no images (renderer none): nothing to export")
    complete = run.get("frames_complete")
    if not isinstance(complete, list) or not complete:
        raise ExportError(f"the run in {run_dir} has no complete frames to export (status {status})")
    if not all(isinstance(name, str) and name for name in complete):
        raise ExportError(f"{run_dir / 'run.json'}: frames_complete must list frame names")
    cameras = _read_json(run_dir / layout.CAMERAS_JSON, "the run wrote no frames, or is half-written")
    intrinsics, known = cameras.get("intrinsics"), cameras.get("frames")
    if not isinstance(known, dict) or not _valid_intrinsics(intrinsics):
        raise ExportError(f"{run_dir / 'cameras.json'} lacks intrinsics (K, width, height) or frames")
    missing = [name for name in complete if name not in known]
    if missing:
        raise ExportError(
            f"{run_dir / 'cameras.json'} lacks frame {missing[0]} that run.json lists complete "
            f"({len(missing)} missing): a half-written run"
        )
    for name in complete:
        pose = known[name].get("world_T_camera") if isinstance(known[name], dict) else None
        try:
            # isfinite sees the pose's own dtype: strings that float64 would parse stay refused
            ok = np.asarray(pose, np.float64).shape == (4, 4) and bool(np.isfinite(np.asarray(pose)).all())
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ExportError(f"{run_dir / 'cameras.json'}: frame {name} has no 4x4 world_T_camera")
        for folder in layout.REQUIRED_FOLDERS:
            if not layout.has_image(run_dir, folder, name):
                raise ExportError(f"{layout.image(run_dir, folder, name)} is missing: a half-written run")
    bench = read_bench(run, run_dir / layout.RUN_JSON, ExportError)
    for name in complete if bench else []:
        if not layout.image(run_dir, layout.PLANTS, name).is_file():
            raise ExportError(f"{layout.image(run_dir, layout.PLANTS, name)} is missing: a half-written bench run")
    width, height = int(intrinsics["width"]), int(intrinsics["height"])
    masks = {name: _mask_png(layout.image(run_dir, "labels", name), width, height) for name in complete}
    # nerfstudio reads PNG depth: an EXR-only run (--depth-format exr) names none
    depth_png = all(layout.image(run_dir, "depth", name).is_file() for name in complete)
    doc = nerfstudio_transforms(intrinsics, {name: known[name] for name in complete}, depth_png, bench_rows(bench))
    if layout.cloud(run_dir, ALL).is_file():
        doc["ply_file_path"] = layout.cloud(Path(), ALL).as_posix()  # splatfacto starts from it: clouds/all.ply

    for name, data in masks.items():
        write_bytes(layout.image(run_dir, layout.MASKS, name), data)
    out = run_dir / layout.TRANSFORMS_JSON
    write_json(out, doc)
    return out


class NerfstudioExporter(Exporter):
    """``agrisim export nerfstudio RUN_DIR``: ``RUN_DIR/transforms.json`` and ``RUN_DIR/masks/``."""

    default_out = layout.TRANSFORMS_JSON

    def export(
        self,
        run_dir: Path,
        out: Path,
        overwrite: bool = False,
        progress: Callable[[int, int], None] | None = None,
    ) -> Path:
        run_dir = Path(run_dir)
        if Path(out).absolute() != (run_dir / layout.TRANSFORMS_JSON).absolute():
            raise ExportError(
                f"the nerfstudio export goes into the run directory ({run_dir / layout.TRANSFORMS_JSON}): its "
                f"transforms.json names the run's images relative to itself; give no OUT"
            )
        return write_nerfstudio(run_dir)


@hookimpl
def agrisim_exporters() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="nerfstudio",
            factory=NerfstudioExporter,
            description="nerfstudio's transforms.json (camera-to-world poses in OpenGL axes, OpenCV lens, depth) "
            "and plant masks (RUN_DIR/masks/), for ns-train --data RUN_DIR; every rendered run writes it itself",
            limits="into the run directory only (its paths are relative to it)",
        )
    ]
