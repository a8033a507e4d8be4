"""What machine a bench figure was measured on: every absolute figure goes out with it."""

from __future__ import annotations

import subprocess


def cpu_model() -> str:
    """The CPU's model name and widest vector ISA, e.g. ``"AMD EPYC 7B13 (AVX2)"``: the engine's
    speed follows the vector width as much as the model (:mod:`agrisim.plugins.render.mitsuba.cpu`)."""
    from agrisim.plugins.render.mitsuba.cpu import cpu_model as model
    from agrisim.plugins.render.mitsuba.cpu import vector_isa

    return f"{model()} ({vector_isa()})"


def gpu_name() -> str:
    """The first NVIDIA GPU's name from ``nvidia-smi`` (``no GPU`` without one)."""
    try:
        out = subprocess.run(
            ["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True, text=True, timeout=20
        )
        return out.stdout.strip().splitlines()[0] if out.returncode == 0 and out.stdout.strip() else "no GPU"
    except (OSError, subprocess.SubprocessError):
        return "no GPU"
