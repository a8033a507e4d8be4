"""How runs and their frames are shared among GPUs, and how many GPUs this machine has, checked
against what they promise: every frame in exactly one part, the GPUs used as evenly as frames
allow, never more parts than GPUs or frames; the count Ray itself would take."""

from __future__ import annotations

import itertools
import os
import stat
from pathlib import Path

import pytest

from agrisim.plugins.apps.placement import local_gpu_count, split_frames, task_resources


def frames(n: int, run: int = 0) -> list[str]:
    return [f"r{run}_{i:03d}" for i in range(n)]


@pytest.mark.parametrize(
    ("sizes", "slots"), list(itertools.product([(100,), (7, 100), (3, 3, 3), (1,), (0, 5)], [1, 2, 3, 4, 8]))
)
def test_every_frame_in_exactly_one_part(sizes: tuple[int, ...], slots: int) -> None:
    runs = [frames(n, i) for i, n in enumerate(sizes)]
    parts = split_frames(runs, slots)
    for i, run in enumerate(runs):
        mine = [p for p in parts if p[0] == i]
        dealt = [f for _, _, fs in mine for f in fs]
        assert sorted(dealt) == sorted(run)
        assert [k for _, k, _ in mine] == list(range(len(mine)))  # part indices 0..n-1
        assert len(mine) <= max(1, len(run))
        lengths = [len(fs) for _, _, fs in mine]
        assert max(lengths) - min(lengths) <= 1  # as even as the frames allow
    assert len(parts) <= max(slots, len(runs))  # never more parts than GPUs, but a run each
    if len(runs) > slots:
        assert len(parts) == len(runs)  # a run a GPU, none split
    elif all(len(r) >= slots for r in runs):
        assert len(parts) == slots  # every GPU has work


def test_one_run_over_four_gpus_is_dealt_round_robin() -> None:
    parts = split_frames([frames(10)], 4)
    assert [fs for _, _, fs in parts] == [frames(10)[k::4] for k in range(4)]


def test_spare_gpus_go_to_the_first_runs() -> None:
    counts = [sum(p[0] == i for p in split_frames([frames(100, i) for i in range(3)], 8)) for i in range(3)]
    assert counts == [3, 3, 2]


def test_no_slots_is_refused() -> None:
    with pytest.raises(ValueError, match="slots"):
        split_frames([frames(3)], 0)


def test_task_resources() -> None:
    assert task_resources(False) == {"num_cpus": 1}
    assert task_resources(True) == {"num_cpus": 1, "num_gpus": 1}
    assert task_resources(True, "h100") == {"num_cpus": 1, "resources": {"h100": 1}}


def fake_smi(folder: Path, listing: str, status: int = 0) -> None:
    smi = folder / "nvidia-smi"
    smi.write_text(f"#!/bin/sh\ncat <<'EOF'\n{listing}EOF\nexit {status}\n")
    smi.chmod(smi.stat().st_mode | stat.S_IEXEC)


def test_gpu_count_as_ray_counts_it(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    listing = "".join(f"GPU {i}: NVIDIA H100 80GB HBM3 (UUID: GPU-{i})\n" for i in range(4))
    fake_smi(tmp_path, listing)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
    assert local_gpu_count() == 4
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "1,3")
    assert local_gpu_count() == 2
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "")
    assert local_gpu_count() == 0
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES")
    fake_smi(tmp_path, "NVIDIA-SMI has failed because it couldn't communicate with the NVIDIA driver\n", 9)
    assert local_gpu_count() == 0
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    assert local_gpu_count() == 0
