"""Where Ray places agrisim's tasks: the resources a task asks for, how one run's frames are
shared among GPUs, how many GPUs this machine has (without starting Ray)."""

from __future__ import annotations

import os
import shutil
import subprocess
from typing import Any


def task_resources(gpu: bool, resource: str = "GPU") -> dict[str, Any]:
    """Ray's options for one task: a core each, and one ``resource`` more for a GPU task (Ray's
    own ``GPU``, which also sets ``CUDA_VISIBLE_DEVICES``, or a custom resource a cluster
    declares its accelerators as)."""
    if not gpu:
        return {"num_cpus": 1}
    if resource == "GPU":
        return {"num_cpus": 1, "num_gpus": 1}
    return {"num_cpus": 1, "resources": {resource: 1}}


def split_frames(runs: list[list[str]], slots: int) -> list[tuple[int, int, list[str]]]:
    """Share ``slots`` GPUs among runs (each a list of frames still to draw): a run per GPU
    where there are as many runs as GPUs or more, else each run's frames dealt out over
    ``slots // len(runs)`` GPUs (the first ``slots % len(runs)`` runs one more), never more
    parts than frames. Returns ``(run index, part index, frames)`` per part, runs in order.

    Frames are dealt round-robin, not in blocks: neighbouring setpoints cost alike (the plant
    fills a side view more than a top view), so each part gets the same mix.
    """
    if slots < 1:
        raise ValueError(f"slots must be 1 or more, got {slots}")
    parts: list[tuple[int, int, list[str]]] = []
    share, extra = divmod(slots, len(runs)) if runs else (0, 0)
    for i, frames in enumerate(runs):
        n = max(1, min(len(frames), share + (i < extra)))
        parts += [(i, k, frames[k::n]) for k in range(n)]
    return parts


def local_gpu_count() -> int:
    """NVIDIA GPUs this process may use, as Ray counts them: ``CUDA_VISIBLE_DEVICES`` where it
    is set, else the GPUs ``nvidia-smi`` lists (0 where there is no driver)."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return len([d for d in visible.split(",") if d.strip() and d.strip() != "-1"])
    smi = shutil.which("nvidia-smi")
    if smi is None:
        return 0
    try:
        listed = subprocess.run([smi, "-L"], capture_output=True, text=True, timeout=20, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return 0
    return sum(line.startswith("GPU ") for line in listed.stdout.splitlines()) if listed.returncode == 0 else 0


__all__ = ["local_gpu_count", "split_frames", "task_resources"]
