"""Materials packed for vectorised lookups at ray hits (the lookups themselves are Dr.Jit code:
:class:`~agrisim.plugins.render.raycast.engine.Engine` and :mod:`.shading`).

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

from typing import Any

import drjit as dr
import numpy as np

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
            texture = np.asarray(texture)
            padded = np.empty((h + 1, w + 1, texture.shape[2]), texture.dtype)
            padded[:h, :w] = texture
            padded[:h, w] = texture[:, 0]  # the wrapped column and row
            padded[h] = padded[0]
            padded = padded.reshape(-1, 4)
            n = len(padded)
            # a channel at a time through its 256 products (float32, as the texel's would be)
            lut = SRGB_TO_LINEAR[:, None] * colour
            for c in range(3):
                self.alb_rgb[off : off + n, c] = np.take(lut[:, c], padded[:, c])
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


class MaterialArrays:
    """A finished :class:`MaterialTable` as Dr.Jit arrays of Mitsuba ``mi``'s variant, and the
    lookups at hits: nearest texels, opacity, labels, albedo."""

    def __init__(self, mi: Any, table: MaterialTable) -> None:
        self.mi = mi
        self.table = table
        self.threshold = mi.Int32(table.threshold.astype(np.int32))
        self.special = mi.Bool(table.special)
        self.double_sided = mi.Bool(table.double_sided)
        self.cuts = mi.Bool(table.cuts)
        self.fallback = mi.UInt32(table.fallback.astype(np.uint32))
        self.alb_alpha = mi.UInt32(table.alb_alpha.astype(np.uint32))
        self.alb_rgb = mi.Float(table.alb_rgb.reshape(-1))
        self.alb_size = (mi.Float(table.alb_wf), mi.Float(table.alb_hf))
        self.lab_flat = mi.UInt32(table.lab_flat.astype(np.uint32))
        self.alb = tuple(
            mi.UInt32(a.astype(np.uint32)) for a in (table.alb_off, table.alb_h, table.alb_w, table.alb_stride)
        )
        self.lab = tuple(mi.UInt32(a.astype(np.uint32)) for a in (table.lab_off, table.lab_h, table.lab_w, table.lab_w))

    def texel(self, uv: Any, mat: Any, packed: tuple, size: int, active: Any = True) -> Any:
        """UInt32 flat index of the nearest texel of ``uv`` in a packed texture buffer
        (``packed``: offset, height, width, row stride per material): float64 product, floor,
        wrap, as the core's texel_index."""
        mi = self.mi
        off, h, w, stride = (dr.gather(mi.UInt32, a, mat, active) for a in packed)
        h, w = dr.maximum(h, 1), dr.maximum(w, 1)  # inactive lanes read 0s, and x % 0 traps
        wi, hi = mi.Int64(w), mi.Int64(h)
        col = mi.Int64(dr.floor(mi.Float64(uv.x) * mi.Float64(w))) % wi
        row = mi.Int64(dr.floor(mi.Float64(uv.y) * mi.Float64(h))) % hi
        col = dr.select(col < 0, col + wi, col)
        row = dr.select(row < 0, row + hi, row)
        index = mi.UInt32(row) * stride + mi.UInt32(col) + off
        return dr.minimum(index, size - 1)  # NaN UVs: any texel, never out of the buffer

    def opaque(self, uv: Any, mat: Any, active: Any = True) -> Any:
        """Bool: is each hit on a texel that opacity keeps? (materials that do not cut: always)"""
        mi = self.mi
        if not self.table.cutting:
            return mi.Bool(True)
        i = self.texel(uv, mat, self.alb, len(self.table.alb_alpha), active)
        alpha = mi.Int32(dr.gather(mi.UInt32, self.alb_alpha, i, active))
        return alpha >= dr.gather(mi.Int32, self.threshold, mat, active)

    def label(self, uv: Any, mat: Any, active: Any = True) -> Any:
        """UInt32 label texel (nearest) of each hit."""
        i = self.texel(uv, mat, self.lab, len(self.table.lab_flat), active)
        return dr.gather(self.mi.UInt32, self.lab_flat, i, active)

    def _rgb(self, i: Any, active: Any) -> Any:
        i3 = i * 3
        return self.mi.Color3f(*(dr.gather(self.mi.Float, self.alb_rgb, i3 + c, active) for c in range(3)))

    @staticmethod
    def _corner(u: Any, size: Any) -> tuple[Any, Any]:
        # first texel (wrapped into [0, size) by float arithmetic) and the weight of the next
        f = u * size - 0.5
        x = dr.floor(f)
        f = f - x
        q = dr.floor(x / size) * size
        return x - q, f

    def albedo(self, uv: Any, mat: Any, bilinear: bool = True, active: Any = True) -> Any:
        """Color3f linear albedo: colour factor times the sRGB texture, if any, sampled nearest
        or bilinearly (in linear light; on cut-out cards only the corners opacity keeps, weights
        renormalised, and where none does the hit's own texel, so the colour of cut-away texels
        never bleeds into a leaf's edge). ``uv`` may be anything on untextured materials."""
        mi = self.mi
        n = len(self.table.alb_alpha)
        nearest = self._rgb(self.texel(uv, mat, self.alb, n, active), active)
        if not bilinear:
            return nearest
        x0, ax = self._corner(uv.x, dr.gather(mi.Float, self.alb_size[0], mat, active))
        y0, ay = self._corner(uv.y, dr.gather(mi.Float, self.alb_size[1], mat, active))
        s = mi.Int64(dr.gather(mi.UInt32, self.alb[3], mat, active))
        i00 = mi.Int64(y0) * s + mi.Int64(x0) + mi.Int64(dr.gather(mi.UInt32, self.alb[0], mat, active))
        corners = [mi.UInt32(dr.clip(i, 0, n - 1)) for i in (i00, i00 + 1, i00 + s, i00 + s + 1)]
        c00, c10, c01, c11 = (self._rgb(c, active) for c in corners)
        top = (c10 - c00) * ax + c00
        bottom = (c11 - c01) * ax + c01
        plain = top + (bottom - top) * ay
        if not self.table.cutting:
            return plain
        cuts = active & dr.gather(mi.Bool, self.cuts, mat, active)
        t = dr.gather(mi.Int32, self.threshold, mat, cuts)
        keep = [dr.select(mi.Int32(dr.gather(mi.UInt32, self.alb_alpha, c, cuts)) >= t, 1.0, 0.0) for c in corners]
        bx, by = 1.0 - ax, 1.0 - ay
        q = [(bx * by) * keep[0], (ax * by) * keep[1], (bx * ay) * keep[2], (ax * ay) * keep[3]]
        total = ((q[0] + q[1]) + q[2]) + q[3]
        q = [w / dr.select(total > 0, total, 1.0) for w in q]
        masked = ((c00 * q[0] + c10 * q[1]) + c01 * q[2]) + c11 * q[3]
        return dr.select(cuts, dr.select(total > 0, masked, nearest), plain)
