"""The training as a Rerun recording, ``splat/training.rrd``, where the Rerun SDK is installed (a
GPU machine's minimal install may not have it): the loss and the number of Gaussians on a
``step`` timeline, each held-out view's truth | render | error image, and the plant's Gaussian
centres in world coordinates (z up). ``rerun RUN/recording.rrd RUN/splat/training.rrd`` opens it
beside the run's own recording (whose clouds are those centres too)."""

from __future__ import annotations

import importlib.util

import numpy as np

APPLICATION = "agrisim-splat"
TIMELINE = "step"


def training_recording(
    loss: list[tuple[int, float, int]],
    tests: dict[str, np.ndarray],
    centres: np.ndarray,
    colors: np.ndarray,
    radii: np.ndarray,
) -> bytes | None:
    """The ``.rrd`` bytes, or None without the Rerun SDK. ``loss`` is (step, loss, Gaussians)
    rows, ``tests`` frame -> H x W x 3 uint8 image, ``centres``/``colors``/``radii`` the plant's
    Gaussians (N x 3 m, N x 3 uint8, N m)."""
    if importlib.util.find_spec("rerun") is None:
        return None
    import rerun as rr

    rec = rr.RecordingStream(APPLICATION)
    memory = rec.memory_recording()
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    if loss:
        rows = np.asarray(loss, np.float64)
        steps = [rr.TimeColumn(TIMELINE, sequence=rows[:, 0].astype(np.int64))]
        # whole columns at once: one chunk each, not one per step
        rec.send_columns("training/loss", indexes=steps, columns=rr.Scalars.columns(scalars=rows[:, 1]))
        rec.send_columns("training/gaussians", indexes=steps, columns=rr.Scalars.columns(scalars=rows[:, 2]))
    for frame, image in tests.items():
        rec.log(f"test/{frame}", rr.Image(image), static=True)
    rec.log("world/splat_centres", rr.Points3D(centres, colors=colors, radii=radii), static=True)
    return memory.drain_as_bytes()
