"""``agrisim render`` over several NVIDIA GPUs: one run's frames dealt out to two parts, each on
its own GPU. Marked ``gpu`` (CI has none; tests/conftest.py skips it); run on a machine of two
or more GPUs from the minimal install with Ray (``bench/device_site.sh --ray``), with
``--noconftest`` and ``AGRISIM_GPU_RUN`` naming a saved run.

Truth: the same run drawn on one GPU by the same code (its frames, its bytes within noise).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from agrisim.plugins.apps.placement import local_gpu_count

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not os.environ.get("AGRISIM_GPU_RUN"), reason="AGRISIM_GPU_RUN names no saved run"),
    pytest.mark.skipif(local_gpu_count() < 2, reason="needs two NVIDIA GPUs"),
]
MITSUBA = {"variant": "cuda", "spp": 4, "denoise": "off"}


def test_one_run_split_over_two_gpus_draws_on_both(tmp_path: Path) -> None:
    from PIL import Image

    from agrisim.plugins.apps.render import RenderPlan, render_runs

    overrides = {"renderer": {"mitsuba": MITSUBA}}
    drawn = {}
    for gpus in (1, 2):
        src = tmp_path / f"run{gpus}"
        shutil.copytree(os.environ["AGRISIM_GPU_RUN"], src)
        plan = RenderPlan(src, "mitsuba", overrides, None, overwrite=False)
        (record,) = render_runs([plan], overrides, gpus=gpus)
        assert "error" not in record, record
        parts = record["parts"]
        assert len(parts) == gpus
        used = [p["gpu_ids"] for p in parts]
        assert all(len(ids) == 1 for ids in used) and len({ids[0] for ids in used}) == gpus, used
        drawn[gpus] = {p.name: np.asarray(Image.open(p), np.int16) for p in sorted((plan.out / "rgb").glob("*.png"))}
        assert sorted(drawn[gpus]) == sorted(f"{f}.png" for f in plan.frames)
    for name, one in drawn[1].items():
        two = drawn[2][name]
        diff = np.abs(one - two)
        print(f"{name}: max {diff.max()}, mean {diff.mean():.4f} levels")  # (the same kernels, seeds and GPU model)
        assert diff.mean() < 0.5 and np.mean(diff > 2) < 0.001
