"""Materials packed for vectorised lookups at ray hits.

Every material's albedo and label textures go into flat buffers, so that the texels of hits on
any mix of materials are one gather: ``index = offset[m] + row * stride[m] + col``. The texel
arithmetic for labels and opacity is that of :func:`agrisim.scene.texturing.texel_index` (float64
product, floor, wrap) and opacity is compared in 8 bits as :func:`agrisim.scene.texturing.opaque` does,
so a renderer using this table labels exactly the texels the core's functions name.

Albedo is stored ready to shade: linear float32 RGB, already multiplied by the material's colour
factor (one copy per texture and colour), each texture padded with a wrapped copy of its first
column and row, so the four texels of a bilinear lookup are ``i, i + 1, i + stride, i + stride +
1`` with no wrapping per hit. An untextured material gets a 1 x 1 texture of its colour (alpha
255), so every hit takes the same path. Label textures are stored as they are (one byte a texel;
an unlabelled material gets its constant label as a 1 x 1 texture).
"""

from __future__ import annotations

import numpy as np

from agrisim.plugins.render.raycast import kernels
from agrisim.scene.colour import srgb_to_linear
from agrisim.scene.model import Material
from agrisim.scene.texturing import alpha_threshold

F32 = np.float32

#: uint8 sRGB -> linear float32
SRGB_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0).astype(F32)



class MaterialTable:
    """Materials by index, their textures in flat buffers (build with :meth:`add`, then
    :meth:`finish`)."""

    def __init__(self) -> None:
        self.materials: list[Material] = []
        self._alb: list[tuple[np.ndarray | None, np.ndarray]] = []  # (texture or None, colour)
        self._alb_size = 0
        self._alb_at: dict[tuple, int] = {}  # (id(texture), colour) -> offset
        self._lab: list[np.ndarray] = []
        self._lab_size = 0
        self._lab_at: dict[int, tuple[int, int]] = {}  # id(texture) -> (offset, most common non-zero)
        self._const_at: dict[int, int] = {}
        self._rows: list[tuple] = []

    def add(self, m: Material) -> int:
        """Index of ``m`` in the table (textures shared between materials of the same colour are
        stored once)."""
        colour = np.asarray(m.color, np.float64)[:3].astype(F32)
        h, w = m.albedo.shape[:2] if m.albedo is not None else (1, 1)
        key = (id(m.albedo) if m.albedo is not None else None, colour.tobytes())
        if key not in self._alb_at:
            self._alb_at[key] = self._alb_size
            self._alb.append((m.albedo, colour))
            self._alb_size += (h + 1) * (w + 1)
        alb = (self._alb_at[key], h, w)
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
        self._rows.append((alb, lab, alpha_threshold(m), common, m.double_sided))
        return len(self.materials) - 1

    def finish(self) -> None:
        rows = self._rows
        # Albedo: linear light x colour factor, each texture padded by a wrapped column and row.
        self.alb_rgb = np.empty((max(self._alb_size, 1), 3), F32)
        self.alb_alpha = np.full(max(self._alb_size, 1), 255, np.uint8)
        off = 0
        for texture, colour in self._alb:
            if texture is None:
                self.alb_rgb[off : off + 4] = colour
                off += 4
                continue
            h, w = texture.shape[:2]
            padded = np.asarray(texture)[np.arange(h + 1) % h][:, np.arange(w + 1) % w].reshape(-1, 4)
            n = len(padded)
            np.multiply(SRGB_TO_LINEAR[padded[:, :3]], colour, out=self.alb_rgb[off : off + n])
            self.alb_alpha[off : off + n] = padded[:, 3]
            off += n
        self.lab_flat = np.concatenate(self._lab) if self._lab else np.zeros(1, np.uint8)
        col = lambda i, j, dtype: np.array([r[i][j] for r in rows], dtype)  # noqa: E731
        self.alb_off, self.alb_h, self.alb_w = col(0, 0, np.int64), col(0, 1, np.int64), col(0, 2, np.int64)
        self.alb_stride = self.alb_w + 1
        self.alb_hf, self.alb_wf = self.alb_h.astype(F32), self.alb_w.astype(F32)
        self.lab_off, self.lab_h, self.lab_w = col(1, 0, np.int64), col(1, 1, np.int64), col(1, 2, np.int64)
        self.threshold = np.array([r[2] for r in rows], np.int16)
        self.fallback = np.array([r[3] for r in rows], np.uint8)
        self.double_sided = np.array([r[4] for r in rows], bool)
        self.cuts = self.threshold > 0
        #: hits on these materials pass on to what lies behind when opaque() says no / back-facing
        self.special = self.cuts | ~self.double_sided
        self.cutting = bool(self.cuts.any())
        self.culling = bool((~self.double_sided).any())
        del self._alb, self._lab

    @staticmethod
    def _index(uv, off, h, w, stride, mat) -> np.ndarray:  # noqa: ANN001
        """Flat index of the nearest texel of each hit in a buffer of textures at ``off`` with
        ``stride`` texels per row. Same arithmetic as agrisim.scene.texturing.texel_index (float64
        product, floor, wrap)."""
        wm, hm = np.take(w, mat), np.take(h, mat)
        cols = np.floor(uv[:, 0].astype(np.float64) * wm).astype(np.int64) % wm
        rows = np.floor(uv[:, 1].astype(np.float64) * hm).astype(np.int64) % hm
        rows *= np.take(stride, mat)
        rows += cols
        rows += np.take(off, mat)
        return rows

    def albedo_index(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        """Index in :attr:`alb_rgb` / :attr:`alb_alpha` of the nearest texel of each hit."""
        return self._index(uv, self.alb_off, self.alb_h, self.alb_w, self.alb_stride, mat)

    def opaque(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        """Is each hit on a texel that opacity keeps? (materials that do not cut: always)"""
        if not self.cutting:
            return np.ones(len(mat), bool)
        return np.take(self.alb_alpha, self.albedo_index(uv, mat)) >= np.take(self.threshold, mat)

    def label(self, uv: np.ndarray, mat: np.ndarray) -> np.ndarray:
        """Label texel (nearest) of each hit."""
        return np.take(self.lab_flat, self._index(uv, self.lab_off, self.lab_h, self.lab_w, self.lab_w, mat))

    def albedo(
        self, uv: np.ndarray, mat: np.ndarray, bilinear: bool = True, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Linear RGB albedo (K x 3 float32, into ``out`` if given): colour factor times the sRGB
        texture, if any, sampled nearest or bilinearly (in linear light; on cut-out cards
        weighted by alpha, so the colour of cut-away texels never bleeds into a leaf's edge).
        ``uv`` may be anything on untextured materials."""
        if not bilinear:
            return np.take(self.alb_rgb, self.albedo_index(uv, mat), axis=0, out=out)
        if out is None:
            out = np.empty((len(mat), 3), F32)
        kernels.albedo_bilinear(
            uv, mat, self.alb_wf, self.alb_hf, self.alb_w, self.alb_h, self.alb_stride, self.alb_off,
            self.alb_rgb, self.alb_alpha, self.threshold, self.cuts, out,
        )
        return out
