"""Image quality as NeRF papers report it: PSNR, and SSIM with an 11 x 11 Gaussian window of
sigma 1.5 (Wang et al. 2004; scikit-image's ``structural_similarity`` with
``gaussian_weights=True, use_sample_covariance=False, data_range=1``, whose border it crops)."""

from __future__ import annotations

import math

import numpy as np

SIGMA = 1.5
RADIUS = 5  # int(3.5 * sigma + 0.5): scikit-image's truncation
K1, K2 = 0.01, 0.03


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Peak signal-to-noise ratio of images in [0, 1] (dB), over ``mask``'s pixels if given."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    if mask is not None:
        d = d[np.asarray(mask, bool)]
    mse = float(np.mean(d * d)) if d.size else float("nan")
    return math.inf if mse == 0.0 else -10.0 * math.log10(mse)


def _window() -> np.ndarray:
    x = np.arange(-RADIUS, RADIUS + 1, dtype=np.float64)
    w = np.exp(-(x * x) / (2.0 * SIGMA * SIGMA))
    return w / w.sum()


def _filter(x: np.ndarray) -> np.ndarray:
    """The Gaussian-weighted mean of every full window (H - 10 x W - 10): separable sums."""
    w = _window()
    n = 2 * RADIUS + 1
    rows = sum(w[i] * x[i : x.shape[0] - n + 1 + i] for i in range(n))
    return sum(w[j] * rows[:, j : rows.shape[1] - n + 1 + j] for j in range(n))


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean structural similarity of two H x W (x C) images in [0, 1], over channels."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.shape != b.shape or min(a.shape[:2]) <= 2 * RADIUS:
        raise ValueError(f"SSIM needs two images of the same shape, larger than 11 x 11; got {a.shape}, {b.shape}")
    c1, c2 = K1 * K1, K2 * K2
    mu_a, mu_b = _filter(a), _filter(b)
    var_a = _filter(a * a) - mu_a * mu_a
    var_b = _filter(b * b) - mu_b * mu_b
    cov = _filter(a * b) - mu_a * mu_b
    s = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a * mu_a + mu_b * mu_b + c1) * (var_a + var_b + c2))
    return float(s.mean())
