"""The paper's split: a seeded random share of the views held out for testing."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from agrisim.errors import UserError


def minimum_views(fraction: float) -> int:
    """The fewest views a split can use: one held out at ``fraction`` (rounded) and at least
    two to train on."""
    return max(math.ceil(0.5 / fraction), 3)


def split_views(frames: Sequence[str], fraction: float, seed: int) -> tuple[list[str], list[str]]:
    """(training frames, test frames), each in the given order: round(n x fraction) views
    (at least one) drawn without replacement by NumPy's PCG64 seeded with ``seed``, so the same
    frames and seed always give the same split."""
    n = len(frames)
    if n < minimum_views(fraction):
        raise UserError(
            f"the run has {n} views; holding out {fraction:.0%} for testing needs at least {minimum_views(fraction)}"
        )
    n_test = min(max(int(math.floor(n * fraction + 0.5)), 1), n - 2)
    held_out = set(np.random.default_rng(seed).choice(n, n_test, replace=False).tolist())
    train = [f for i, f in enumerate(frames) if i not in held_out]
    test = [f for i, f in enumerate(frames) if i in held_out]
    return train, test
