"""Cameras as gsplat takes them.

gsplat's ``rasterization`` takes world-to-camera matrices in OpenCV's convention (x right,
y down, z forward), the agrisim pose inverted, and a pinhole K; but its rasteriser puts the
centre of pixel (row i, column j) at (j + 0.5, i + 0.5), where OpenCV puts it at (j, i). So
gsplat gets K with the principal point moved by +0.5 px: a point K sends to OpenCV pixel
(u, v) lands on gsplat's pixel centre (u + 0.5, v + 0.5), the same pixel. Downscaling the
images by an integer factor k (k x k blocks averaged) divides those corner-origin coordinates
by k: K's first two rows are divided by k after the shift.
"""

from __future__ import annotations

import numpy as np


def gsplat_camera(K: np.ndarray, world_T_camera: np.ndarray, downscale: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(viewmat, K) for gsplat: the 4 x 4 world-to-camera matrix and the 3 x 3 intrinsics of
    the image downscaled by ``downscale``, both float64."""
    T = np.asarray(world_T_camera, np.float64)
    R, t = T[:3, :3], T[:3, 3]
    viewmat = np.eye(4)
    viewmat[:3, :3] = R.T
    viewmat[:3, 3] = -R.T @ t
    Kg = np.asarray(K, np.float64).copy()
    Kg[0, 2] += 0.5
    Kg[1, 2] += 0.5
    Kg[:2] /= float(downscale)
    return viewmat, Kg


def downscale_image(image: np.ndarray, k: int) -> np.ndarray:
    """The mean of every k x k block (rows and columns beyond a whole block are dropped)."""
    if k == 1:
        return image
    h, w = image.shape[0] // k * k, image.shape[1] // k * k
    blocks = image[:h, :w].reshape(h // k, k, w // k, k, *image.shape[2:])
    return blocks.mean(axis=(1, 3))
