"""Materials packed for vectorised lookups at ray hits.

Every material's albedo and label textures go into two flat buffers, so that the texels of hits on
any mix of materials are one gather: ``index = offset[m] + row * width[m] + col``. Untextured
materials get a 1 x 1 texture (white albedo, their constant label). The texel arithmetic is that of
:func:`agrisim.texturing.texel_index` (float64 product, floor, wrap) and opacity is compared in
8 bits as :func:`agrisim.texturing.opaque` does, so a renderer using this table labels exactly
the texels the core's functions name.
"""

from __future__ import annotations

import numpy as np

from agrisim.scene import Material

F32 = np.float32

#: uint8 sRGB -> linear float32
SRGB_TO_LINEAR = np.where(
    np.arange(256) / 255.0 <= 0.04045, np.arange(256) / 255.0 / 12.92, ((np.arange(256) / 255.0 + 0.055) / 1.055) ** 2.4
).astype(F32)


def alpha_threshold(material: Material) -> int:
    """Smallest 8-bit texture alpha that ``material`` keeps (0 when opacity cuts nothing; 256
    when it keeps nothing). glTF: alpha is the texel's times the colour factor's, compared with
    the same float operations as :func:`agrisim.texturing.opaque`; an untextured material reads
    the table's white texel (alpha 255)."""
    if not material.cuts:
        return 0
    ok = np.arange(256, dtype=np.float64) / 255.0 * float(material.color[3]) >= material.alpha_cutoff
    return int(np.argmax(ok)) if ok.any() else 256


class MaterialTable:
    """Materials by index, their textures in flat buffers (build with :meth:`add`, then
    :meth:`finish`)."""

    def __init__(self) -> None:
        self.materials: list[Material] = []
        self._alb: list[np.ndarray] = [np.full((1, 4), 255, np.uint8)]  # shared white texel
        self._alb_size = 1
        self._lab: list[np.ndarray] = []
        self._lab_size = 0
        self._alb_at: dict[int, int] = {}
        self._lab_at: dict[int, tuple[int, int]] = {}  # id(texture) -> (offset, most common non-zero)
        self._const_at: dict[int, int] = {}
        self._rows: list[tuple] = []

    def add(self, m: Material) -> int:
        """Index of ``m`` in the table (textures shared between materials are stored once)."""
        if m.albedo is not None:
            key = id(m.albedo)
            if key not in self._alb_at:
                self._alb_at[key] = self._alb_size
                flat = np.ascontiguousarray(m.albedo).reshape(-1, 4)
                self._alb.append(flat)
                self._alb_size += len(flat)
            alb = (self._alb_at[key], *m.albedo.shape[:2])
        else:
            alb = (0, 1, 1)
        if m.labels is not None:
            key = id(m.labels)
            if key not in self._lab_at:
                flat = np.ascontiguousarray(m.labels).reshape(-1)
                counts = np.bincount(flat, minlength=256)
                counts[0] = 0
                common = int(counts.argmax()) if counts.any() else int(m.label)
                self._lab_at[key] = (self._lab_size, common)
                self._lab.append(flat)
                self._lab_size += len(flat)
            off, common = self._lab_at[key]
            lab = (off, *m.labels.shape[:2])
        else:
            if m.label not in self._const_at:
                self._const_at[m.label] = self._lab_size
                self._lab.append(np.array([m.label], np.uint8))
                self._lab_size += 1
            lab, common = (self._const_at[m.label], 1, 1), int(m.label)
        self.materials.append(m)
        self._rows.append((alb, lab, alpha_threshold(m), common, m.double_sided, m.color, m.albedo is not None))
        return len(self.materials) - 1

    def finish(self) -> None:
        rows = self._rows
        flat = np.concatenate(self._alb)
        self.alb_rgb = np.ascontiguousarray(flat[:, :3])
        self.alb_alpha = np.ascontiguousarray(flat[:, 3])
        self.lab_flat = np.concatenate(self._lab) if self._lab else np.zeros(1, np.uint8)
        col = lambda i, j, dtype: np.array([r[i][j] for r in rows], dtype)  # noqa: E731
        self.alb_off, self.alb_h, self.alb_w = col(0, 0, np.int64), col(0, 1, np.int64), col(0, 2, np.int64)
        self.lab_off, self.lab_h, self.lab_w = col(1, 0, np.int64), col(1, 1, np.int64), col(1, 2, np.int64)
        self.threshold = np.array([r[2] for r in rows], np.int16)
        self.fallback = np.array([r[3] for r in rows], np.uint8)
        self.double_sided = np.array([r[4] for r in rows], bool)
        self.color = np.array([r[5] for r in rows], np.float64).reshape(-1, 4)[:, :3].astype(F32)
        self.has_albedo = np.array([r[6] for r in rows], bool)
        self.cuts = self.threshold > 0
        #: hits on these materials pass on to what lies behind when opaque() says no / back-facing
        self.special = self.cuts | ~self.double_sided
        self.cutting = bool(self.cuts.any())
        self.culling = bool((~self.double_sided).any())
        # Where UVs are needed at all: textured materials (untextured ones read their 1x1 texels).
        self.textured = np.array([r[0][1] * r[0][2] > 1 or r[1][1] * r[1][2] > 1 for r in rows], bool)

    @staticmethod
    def _index(uv: np.ndarray, off: np.ndarray, h: np.ndarray, w: np.ndarray, mat: np.ndarray) -> np.ndarray:
        # Same arithmetic as agrisim.texturing.texel_index (float64 product, floor, wrap).
        wm, hm = np.take(w, mat), np.take(h, mat)
        cols = np.floor(uv[:, 0].astype(np.float64) * wm).astype(np.int64) % wm
        rows = np.floor(uv[:, 1].astype(np.float64) * hm).astype(np.int64) % hm
        rows *= wm
        rows += cols
        rows += np.take(off, mat)
        return rows

    def albedo_index(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        return self._index(uv, self.alb_off, self.alb_h, self.alb_w, mat)

    def opaque(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        """Is each hit on a texel that opacity keeps? (materials that do not cut: always)"""
        if not self.cutting:
            return np.ones(len(mat), bool)
        return np.take(self.alb_alpha, self.albedo_index(uv, mat)) >= np.take(self.threshold, mat)

    def label(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        """Label texel (nearest) of each hit."""
        return np.take(self.lab_flat, self._index(uv, self.lab_off, self.lab_h, self.lab_w, mat))

    def albedo(self, uv: np.ndarray, mat: np.ndarray, bilinear: bool = True) -> np.ndarray:
        """Linear RGB albedo (K x 3 float32): colour factor times the sRGB texture, if any,
        sampled nearest or bilinearly (in linear light; on cut-out cards weighted by alpha, so
        the colour of cut-away texels never bleeds into a leaf's edge)."""
        out = np.take(self.color, mat, axis=0)
        sel = np.flatnonzero(np.take(self.has_albedo, mat))
        if not len(sel):
            return out
        uv, mat = np.take(uv, sel, axis=0), mat[sel]
        if not bilinear:
            out[sel] *= SRGB_TO_LINEAR[np.take(self.alb_rgb, self.albedo_index(uv, mat), axis=0)]
            return out
        w, h, off = np.take(self.alb_w, mat), np.take(self.alb_h, mat), np.take(self.alb_off, mat)
        fx = uv[:, 0] * w.astype(F32) - F32(0.5)
        fy = uv[:, 1] * h.astype(F32) - F32(0.5)
        x0, y0 = np.floor(fx), np.floor(fy)
        ax, ay = (fx - x0)[:, None], (fy - y0)[:, None]
        x0 = x0.astype(np.int64) % w
        y0 = y0.astype(np.int64) % h
        x1 = x0 + 1
        x1[x1 == w] = 0
        y1 = y0 + 1
        y1[y1 == h] = 0
        y0 *= w
        y0 += off
        y1 *= w
        y1 += off
        corners = ((y0 + x0, (1 - ax) * (1 - ay)), (y0 + x1, ax * (1 - ay)), (y1 + x0, (1 - ax) * ay), (y1 + x1, ax * ay))
        cut = np.flatnonzero(np.take(self.cuts, mat))
        if len(cut):  # alpha-weighted: only kept texels give their colour
            weights = []
            for index, weight in corners:
                weight = weight.copy()
                keep = np.take(self.alb_alpha, index[cut]) >= np.take(self.threshold, mat[cut])
                weight[cut] *= keep[:, None]
                weights.append(weight)
            total = sum(weights)
            empty = total[:, 0] <= 0  # (no kept corner: the hit's own texel decides)
            total[empty] = 1.0
            corners = tuple((c[0], wt / total) for c, wt in zip(corners, weights))
            if empty.any():
                nearest = SRGB_TO_LINEAR[np.take(self.alb_rgb, self.albedo_index(uv[empty], mat[empty]), axis=0)]
        color = np.zeros((len(sel), 3), F32)
        for index, weight in corners:
            color += SRGB_TO_LINEAR[np.take(self.alb_rgb, index, axis=0)] * weight
        if len(cut) and empty.any():
            color[empty] = nearest
        out[sel] *= color
        return out
