"""Vertex colours in Mitsuba: a texture that multiplies another by the mesh's vertex colour
(glTF's ``COLOR_0``, :attr:`agrisim.scene.model.Mesh.colors`), interpolated over the triangle
as Mitsuba's ``Mesh.eval_attribute_3`` interpolates a vertex attribute. None of Mitsuba's
textures multiplies two, so this one is written in Python (Dr.Jit traces it into the kernel like
any other texture, on the CPU and the GPU).

The colours are not read through ``si.shape.eval_attribute_3``: that is a call on the shape
(``si.shape`` is an array of pointers), nested in the BSDF's call, and Dr.Jit gives each nested
call site its own table at a fixed place in the kernel's data, so BSDFs whose code is otherwise
the same (the leaf cards of two materials, and every BSDF nested in them: Dr.Jit traces each
one alive) no longer share a compiled function: the 48 x 36 view of the lab with a hydrangea
compiled a path-tracing kernel of 62.5k operations (5.2 MB of LLVM IR), 23.4k without those
calls. :class:`VertexColours` keeps instead the tinted meshes' triangles, vertex positions and
colours in one place, a table from the shape's registry id (the value of ``si.shape``) to its
first triangle there, and interpolates them with Mitsuba's own arithmetic
(``Mesh::barycentric_coordinates``, ``Mesh::interpolate_attribute``): the same bits, from
gathers alone, the same code in every tinted BSDF.

:func:`tinted` wraps a colour (a texture object or an ``rgb`` dict) for a mesh that has colours;
:func:`register` makes the plugin known to the current variant once.
"""

from __future__ import annotations

import itertools
import weakref
from typing import Any

import drjit as dr
import numpy as np

PLUGIN = "agrisim_vertex_tint"
ATTRIBUTE = "vertex_color"

_registered: set[str] = set()
_keys = itertools.count(1)
#: the live stores by key (a texture's ``colours`` property: Mitsuba's properties hold no Python
#: objects); weak: a store lives while its scene is built, its textures then hold its arrays
_stores: weakref.WeakValueDictionary[int, VertexColours] = weakref.WeakValueDictionary()


class VertexColours:
    """The vertex colours of one scene's tinted meshes, for :class:`VertexTint` to read by the
    shape's registry id: :meth:`add` each tinted shape, then :meth:`finish`. The vertex
    positions are a copy of the shape's, so its vertices must not move afterwards (the arms,
    which do, carry no colours)."""

    def __init__(self) -> None:
        self.key = next(_keys)
        _stores[self.key] = self
        self._parts: list[tuple[int, np.ndarray, np.ndarray, np.ndarray]] = []
        self.arrays: tuple[Any, Any, Any, Any] | None = None
        #: the textures that read these colours, given the arrays by :meth:`finish`
        self.textures: list[Any] = []

    def add(self, mi: Any, shape: Any, vertices: np.ndarray, faces: np.ndarray, colours: np.ndarray) -> None:
        """Keep ``shape``'s triangles, vertices (as the shape has them, float32) and colours."""
        shape_id = int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])
        self._parts.append((shape_id, np.asarray(vertices, np.float32), np.asarray(faces, np.uint32), colours))

    def finish(self, mi: Any) -> None:
        """Gather the shapes' data into the arrays the textures read."""
        if not self._parts:
            return
        base = np.zeros(max(p[0] for p in self._parts) + 1, np.uint32)
        faces, vertices, colours = [], [], []
        n_faces = n_vertices = 0
        for shape_id, v, f, c in self._parts:
            base[shape_id] = n_faces
            faces.append(f + np.uint32(n_vertices))
            vertices.append(v)
            colours.append(np.asarray(c, np.float32))
            n_faces += len(f)
            n_vertices += len(v)
        self.arrays = (
            mi.UInt32(base),
            mi.UInt32(np.concatenate(faces).ravel()),
            mi.Float(np.concatenate(vertices).ravel()),
            mi.Float(np.concatenate(colours).ravel()),
        )
        self._parts = []
        # Each texture holds the arrays itself: a frozen function (dr.freeze) finds the
        # variables a Python plugin reads among the plugin's own attributes (Dr.Jit arrays,
        # tuples of them), not inside another Python object; reading them from this store made
        # the recording fail on CUDA ("a virtual function call ... no such object instance")
        for texture in self.textures:
            texture.tint_arrays = self.arrays
        self.textures = []

    def eval(self, mi: Any, si: Any, active: Any) -> Any:
        """The vertex colour at ``si``: bit for bit ``si.shape.eval_attribute_3(ATTRIBUTE, si)``
        (Mitsuba 3.9's ``Mesh::interpolate_attribute``), zero where not ``active`` as there."""
        assert self.arrays is not None, "VertexColours.finish was not called"
        return colour_at(mi, self.arrays, si, active)


def colour_at(mi: Any, arrays: tuple[Any, Any, Any, Any], si: Any, active: Any) -> Any:
    """The vertex colour at ``si`` from a :class:`VertexColours`' ``arrays``: bit for bit
    ``si.shape.eval_attribute_3(ATTRIBUTE, si)`` (Mitsuba 3.9's ``Mesh::interpolate_attribute``),
    zero where not ``active`` as there."""
    base, faces, positions, colours = arrays
    shape = dr.reinterpret_array(mi.UInt32, si.shape)
    face = dr.gather(mi.UInt32, base, shape, active) + si.prim_index
    fi = [dr.gather(mi.UInt32, faces, face * 3 + k, active) for k in range(3)]
    p0, p1, p2 = (dr.gather(mi.Point3f, positions, i, active) for i in fi)
    rel, du, dv = si.p - p0, p1 - p0, p2 - p0

    def dot(a: Any, b: Any) -> Any:  # (Dr.Jit's C++ dot: a product, then fused steps)
        return dr.fma(a.z, b.z, dr.fma(a.y, b.y, a.x * b.x))

    b1, b2 = dot(du, rel), dot(dv, rel)
    a11, a12, a22 = dot(du, du), dot(du, dv), dot(dv, dv)
    inv_det = dr.rcp(a11 * a22 - a12 * a12)
    u = dr.fma(a22, b1, -(a12 * b2)) * inv_det  # fmsub
    v = dr.fma(-a12, b1, a11 * b2) * inv_det  # fnmadd
    w = 1.0 - u - v
    c0, c1, c2 = (dr.gather(mi.Color3f, colours, i, active) for i in fi)
    return dr.select(active, dr.fma(c0, w, dr.fma(c1, u, c2 * v)), 0.0)


def register(mi: Any) -> None:
    """Register the texture with Mitsuba's current variant (again for each variant used)."""
    if mi.variant() in _registered:
        return

    class VertexTint(mi.Texture):  # type: ignore[misc, name-defined]
        """``texture`` times the shape's vertex colour."""

        def __init__(self, props: Any) -> None:
            mi.Texture.__init__(self, props)
            self.nested = props.get_texture("texture")
            self.tint_arrays: tuple[Any, Any, Any, Any] | None = None  # (VertexColours.finish)
            _stores[int(props.get("colours"))].textures.append(self)

        def eval(self, si: Any, active: Any = True) -> Any:
            assert self.tint_arrays is not None, "VertexColours.finish was not called"
            tint = colour_at(mi, self.tint_arrays, si, active)
            return self.nested.eval(si, active) * mi.Color3f(tint)

        def eval_1(self, si: Any, active: Any = True) -> Any:
            return dr.mean(self.eval(si, active))

        def mean(self) -> Any:
            return self.nested.mean()

        def is_spatially_varying(self) -> bool:
            return True

        def traverse(self, callback: Any) -> None:
            callback.put("texture", self.nested, mi.ParamFlags.NonDifferentiable)

    mi.register_texture(PLUGIN, lambda props: VertexTint(props))
    _registered.add(mi.variant())


def tinted(colour: Any, colours: VertexColours) -> dict:
    """``colour`` (a Mitsuba texture or a texture dict) times the vertex colour of ``colours``."""
    return {"type": PLUGIN, "texture": colour, "colours": colours.key}
