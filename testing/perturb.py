"""Runs perturbed as another machine would render them, to show that what reads them is robust
rather than lucky.

Two CPUs draw the same scene a grey level apart here and there: Embree's and Dr.Jit's kernels
differ with the vector width (AVX2 or AVX-512) and round differently. A pipeline that turns on
such differences (COLMAP at its own SIFT threshold placed 18, 2 or 0 of the same 36 views) gives
one machine's answer, not the method's.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from PIL import Image

from agrisim.errors import OutputError
from agrisim.files import layout
from agrisim.files.png import encode_png
from agrisim.files.rundir import read_run


def noisy_copy(run_dir: Path, out: Path, seed: int, levels: int = 1) -> Path:
    """A copy at ``out`` of the complete run in ``run_dir`` whose RGB views are re-encoded with
    independent uniform integer noise in ``[-levels, levels]`` grey levels a pixel and channel
    (clipped to 0..255), drawn from ``seed``; every other file copied as it is, but for COLMAP's
    model of the views (``colmap/``), which the noise makes stale."""
    run_dir = Path(run_dir)
    run, _ = read_run(run_dir)
    if Path(out).exists():
        raise OutputError(f"{out} already exists")
    shutil.copytree(run_dir, out, ignore=lambda folder, _: [layout.COLMAP] if Path(folder) == run_dir else [])
    rng = np.random.default_rng(seed)
    for frame in sorted(run.get("frames_complete") or []):
        path = layout.image(out, "rgb", frame)
        with Image.open(path) as im:
            rgb = np.asarray(im).astype(np.int16)
        rgb += rng.integers(-levels, levels + 1, rgb.shape, dtype=np.int16)
        path.write_bytes(encode_png(np.clip(rgb, 0, 255).astype(np.uint8)))
    return Path(out)
