"""Splats as the PLY that 3D Gaussian splatting viewers open (the layout of the original
implementation, which SuperSplat, the antimatter15 and gsplat.js viewers and nerfstudio read):
one vertex per Gaussian with float32 properties, in this order:

``x y z`` centre (world, metres); ``nx ny nz`` zero (unused); ``f_dc_0..2`` the degree-0
spherical harmonics coefficient per colour; ``f_rest_*`` the higher degrees, all of red's
coefficients, then green's, then blue's; ``opacity`` before the sigmoid; ``scale_0..2`` the
log of the standard deviations along the Gaussian's axes; ``rot_0..3`` its rotation as a
quaternion (w, x, y, z), not necessarily normalised.
"""

from __future__ import annotations

import numpy as np


def splat_ply(
    means: np.ndarray,
    quats: np.ndarray,
    log_scales: np.ndarray,
    opacity_logits: np.ndarray,
    sh0: np.ndarray,
    sh_rest: np.ndarray,
) -> bytes:
    """The PLY bytes of N Gaussians: ``means`` (N, 3), ``quats`` (N, 4) w x y z,
    ``log_scales`` (N, 3), ``opacity_logits`` (N,), ``sh0`` (N, 3) and ``sh_rest`` (N, K, 3)
    spherical harmonics coefficients (gsplat's layout: coefficient, then colour)."""
    n = len(means)
    k = sh_rest.shape[1] if sh_rest.ndim == 3 else 0
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(3 * k)]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    columns = [
        np.asarray(means, np.float32).reshape(n, 3),
        np.zeros((n, 3), np.float32),
        np.asarray(sh0, np.float32).reshape(n, 3),
        np.asarray(sh_rest, np.float32).reshape(n, k, 3).transpose(0, 2, 1).reshape(n, 3 * k),
        np.asarray(opacity_logits, np.float32).reshape(n, 1),
        np.asarray(log_scales, np.float32).reshape(n, 3),
        np.asarray(quats, np.float32).reshape(n, 4),
    ]
    data = np.ascontiguousarray(np.concatenate(columns, axis=1), "<f4")
    header = f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\n"
    header += "".join(f"property float {name}\n" for name in names) + "end_header\n"
    return header.encode() + data.tobytes()
