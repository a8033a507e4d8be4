"""The Wavefront OBJ + MTL reader: positions, UVs, faces and materials with their textures and
opacity maps, into a :class:`RawMesh`. :mod:`agrisim.plugins.formats.plant_asset` documents what is honoured.

By hand, not trimesh's OBJ loader (``bench/gltf_equality.py --why-not-trimesh`` shows the
first, the indices and the split): it takes a ``map_Kd``'s options as part of the file name and
then drops the texture without a word, ignores ``map_d`` and ``-imfchan``/``-o``/``-s``, reads
only the first ``mtllib``, resolves negative indices against the whole file instead of the
vertices before the face, and splits the faces into one mesh per material (reordered), where
agrisim keeps one mesh in file order and refuses what it cannot read with a message that names
the file and line."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from agrisim.plugins.formats.asset_reading import AssetError, RawMesh, decode_image, locate, read_bytes_of, rgba_array
from agrisim.scene.model import Material

# --------------------------------------------------------------------------------------------

_MTL_OPTION_ARGS = {
    "-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
    "-texres": 1, "-type": 1, "-mm": 2, "-o": 3, "-s": 3, "-t": 3,
}  # fmt: skip


@dataclass
class _MtlMaterial:
    name: str
    kd: tuple[float, float, float] = (0.8, 0.8, 0.8)
    d: float = 1.0
    map_kd: tuple[dict[str, list[str]], str] | None = None
    map_d: tuple[dict[str, list[str]], str] | None = None
    source: str = ""  # the MTL file, for messages
    folder: Path = Path(".")


# One line-by-line loop over OBJ statements; split, its running state (vertices, groups, material) would be scattered.
def read_obj(path: Path, shown: str, root: Path | None) -> RawMesh:
    data = read_bytes_of(path, shown)
    if b"\x00" in data[:4096]:
        raise AssetError(f"{shown}: not a mesh (a binary file, not a text OBJ)")
    text = data.decode("utf-8", errors="replace")
    text = re.sub(r"\\\r?\n", " ", text)  # line continuations

    v_rows: list[list[str]] = []
    vt_rows: list[list[str]] = []
    corner_v: list[int] = []
    corner_vt: list[int] = []
    face_mat: list[int] = []
    mat_names: list[str] = []
    mat_index: dict[str, int] = {}
    current = -1
    mtllibs: list[str] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line[0] == "#":
            continue
        key, _, rest = line.partition(" ")
        if "\t" in key:
            key, _, rest = line.replace("\t", " ").partition(" ")
        if key == "v":
            parts = rest.split()
            if len(parts) < 3:
                raise AssetError(f"{shown}: line {lineno}: a vertex needs 3 coordinates")
            v_rows.append(parts[:3])
        elif key == "vt":
            parts = rest.split()
            if not parts:
                raise AssetError(f"{shown}: line {lineno}: a texture coordinate needs a value")
            vt_rows.append([parts[0], parts[1] if len(parts) > 1 else "0"])
        elif key == "f":
            nv, nt = len(v_rows), len(vt_rows)
            vs, ts = [], []
            try:
                for tok in rest.split():
                    sub = tok.split("/")
                    i = int(sub[0])
                    vs.append(i - 1 if i > 0 else nv + i if i < 0 else -(10**12))
                    if len(sub) > 1 and sub[1]:
                        j = int(sub[1])
                        ts.append(j - 1 if j > 0 else nt + j if j < 0 else -(10**12))
                    else:
                        ts.append(-1)
            except ValueError:
                raise AssetError(f"{shown}: line {lineno}: malformed face {rest.strip()!r}") from None
            if len(vs) < 3:
                raise AssetError(f"{shown}: line {lineno}: a face needs at least 3 vertices")
            if min(vs) < 0:
                raise AssetError(f"{shown}: line {lineno}: face refers to a vertex that does not exist")
            if any(t < -1 for t in ts):
                raise AssetError(f"{shown}: line {lineno}: face refers to a texture coordinate that does not exist")
            if current < 0:
                current = mat_index.setdefault("default", len(mat_names))
                if current == len(mat_names):
                    mat_names.append("default")
            for k in range(1, len(vs) - 1):  # fan
                corner_v += [vs[0], vs[k], vs[k + 1]]
                corner_vt += [ts[0], ts[k], ts[k + 1]]
                face_mat.append(current)
        elif key == "usemtl":
            mname = rest.strip() or "default"
            if mname not in mat_index:
                mat_index[mname] = len(mat_names)
                mat_names.append(mname)
            current = mat_index[mname]
        elif key == "mtllib":
            mtllibs.append(rest.strip())

    if not v_rows and not corner_v:
        raise AssetError(f"{shown}: not a mesh (no OBJ vertex or face statements)")
    if not corner_v:
        raise AssetError(f"{shown}: no triangles (the OBJ has vertices but no faces)")
    try:
        positions = np.array(v_rows, dtype=np.float64)
        texcoords = np.array(vt_rows, dtype=np.float64).reshape(-1, 2)
    except ValueError as e:
        raise AssetError(f"{shown}: a vertex or texture coordinate is not a number ({e})") from None
    cv = np.asarray(corner_v, np.int64)
    ct = np.asarray(corner_vt, np.int64)
    if cv.max() >= len(positions):
        raise AssetError(f"{shown}: a face refers to vertex {int(cv.max()) + 1}, but the file has {len(positions)}")
    if ct.max(initial=-1) >= len(texcoords):
        raise AssetError(
            f"{shown}: a face refers to texture coordinate {int(ct.max()) + 1}, but the file has {len(texcoords)}"
        )

    library = _read_mtllibs(mtllibs, path, shown, root)
    materials, transforms, tex_names = [], [], []
    for mname in mat_names:
        mat, transform, tex_name = _obj_material(library.get(mname), mname, shown, root)
        materials.append(mat)
        transforms.append(transform)
        tex_names.append(tex_name)

    # One agrisim vertex per distinct (position, texture coordinate, texture transform).
    fm = np.repeat(np.asarray(face_mat, np.int64), 3)
    tf_ids = {t: i for i, t in enumerate(dict.fromkeys(t for t in transforms if t is not None), 1)}
    corner_tf = np.array([tf_ids.get(t, 0) if t else 0 for t in transforms], np.int64)[fm]
    keys = (cv * (len(texcoords) + 1) + (ct + 1)) * (len(tf_ids) + 1) + corner_tf
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # vertices in order of first use
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    corner_vertex = rank[inverse.ravel()]
    first_corner = first[order]
    vertex_pos = cv[first_corner]
    vertex_vt = ct[first_corner]
    vertex_tf = corner_tf[first_corner]

    has_uv = vertex_vt >= 0
    uvs = None
    if has_uv.any():
        st = np.where(has_uv[:, None], texcoords[np.maximum(vertex_vt, 0)], 0.0)
        inv_tf = {i: t for t, i in tf_ids.items()}
        for i, (su, sv, ou, ov) in inv_tf.items():
            sel = vertex_tf == i
            st[sel] = st[sel] * [su, sv] + [ou, ov]
        uvs = np.column_stack([st[:, 0], np.where(has_uv, 1.0 - st[:, 1], 0.0)]).astype(np.float32)  # OBJ v is up
    return RawMesh(
        positions=positions[vertex_pos],
        faces=corner_vertex.reshape(-1, 3),
        face_material=np.asarray(face_mat, np.int64),
        materials=materials,
        uvs=uvs,
        has_uv=has_uv,
        texture_names=tex_names,
    )


def _read_mtllibs(names: list[str], obj: Path, shown: str, root: Path | None) -> dict[str, _MtlMaterial]:
    library: dict[str, _MtlMaterial] = {}
    for name in names:
        rel = name.replace("\\", "/")
        where = f"{shown}: material library '{rel}'"
        candidates = [rel] if (obj.parent / rel).exists() or " " not in rel else [rel, *rel.split()]
        found = False
        for cand in candidates:
            real = locate(Path(cand), root, where, base=obj.parent, must_exist=False)
            if real.is_file():
                _parse_mtl(read_bytes_of(real, where).decode("utf-8", errors="replace"), real, where, library)
                found = True
        if not found:
            raise AssetError(f"{where} not found (next to the OBJ, in {obj.parent})")
    return library


def _parse_mtl(text: str, path: Path, where: str, library: dict[str, _MtlMaterial]) -> None:
    cur: _MtlMaterial | None = None
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line[0] == "#":
            continue
        parts = line.split(None, 1)
        key, rest = parts[0].lower(), (parts[1].strip() if len(parts) > 1 else "")
        try:
            if key == "newmtl":
                cur = library.setdefault(rest, _MtlMaterial(rest, source=where, folder=path.parent))
            elif cur is None:
                continue
            elif key == "kd":
                vals = [float(x) for x in rest.split()[:3]]
                cur.kd = (vals[0], vals[0], vals[0]) if len(vals) == 1 else (vals[0], vals[1], vals[2])
            elif key == "d":
                cur.d = float(rest.split()[-1])  # "d -halo 0.5" keeps the value
            elif key in ("map_kd", "map_d"):
                setattr(cur, key, _texture_statement(rest))
        except (ValueError, IndexError):
            raise AssetError(f"{where}: line {lineno}: malformed {parts[0]} statement") from None


def _texture_statement(rest: str) -> tuple[dict[str, list[str]], str]:
    """Options and file name of a ``map_*`` statement (the file name may contain spaces)."""
    tokens = list(re.finditer(r"\S+", rest))
    opts: dict[str, list[str]] = {}
    i = 0
    while i < len(tokens) and tokens[i].group().lower() in _MTL_OPTION_ARGS:
        opt = tokens[i].group().lower()
        n = _MTL_OPTION_ARGS[opt]
        i += 1
        vals: list[str] = []
        while len(vals) < n and i < len(tokens) - 1:  # never eat the file name
            tok = tokens[i].group()
            if n == 3 and vals and not _is_number(tok):
                break
            vals.append(tok)
            i += 1
        opts[opt] = vals
    if i >= len(tokens):
        raise ValueError("no file name")
    return opts, rest[tokens[i].start() :].strip()


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _obj_material(
    m: _MtlMaterial | None, name: str, shown: str, root: Path | None
) -> tuple[Material, tuple[float, float, float, float] | None, str | None]:
    """The agrisim material of an MTL material, its UV transform (su, sv, ou, ov) and texture name."""
    if m is None:  # usemtl without a library entry: plain grey
        return Material(name, (0.8, 0.8, 0.8, 1.0), label=1, double_sided=True), None, None
    rgb, albedo, mode, tex_name, transform = m.kd, None, "OPAQUE", None, None
    if m.map_kd is not None:
        opts, fname = m.map_kd
        img = _obj_texture(m, fname, root)
        albedo = rgba_array(img).copy()
        rgb, tex_name = (1.0, 1.0, 1.0), fname
        if albedo[..., 3].min() < 255:
            mode = "MASK"
        transform = _mtl_uv_transform(opts)
    if m.map_d is not None:
        opts, fname = m.map_d
        alpha = _matte(_obj_texture(m, fname, root), (opts.get("-imfchan") or ["m"])[0])
        if albedo is None:
            albedo = np.full((*alpha.shape, 4), 255, np.uint8)
            tex_name = fname
            transform = _mtl_uv_transform(opts)
        elif alpha.shape != albedo.shape[:2]:
            h, w = albedo.shape[:2]
            alpha = np.asarray(Image.fromarray(alpha, "L").resize((w, h), Image.Resampling.NEAREST))
        albedo[..., 3] = alpha
        mode = "MASK"
    d = float(m.d)
    if not 0.0 <= d <= 1.0:
        raise AssetError(f"{m.source}: material '{name}' has dissolve d {d}, outside 0..1")
    if d < 1.0 and mode == "OPAQUE":
        mode = "BLEND"
    mat = Material(
        name,
        color=(float(rgb[0]), float(rgb[1]), float(rgb[2]), d),
        albedo=albedo,
        label=1,
        alpha_mode=mode,  # type: ignore[arg-type]
        alpha_cutoff=0.5,
        double_sided=True,
    )
    return mat, transform, tex_name


def _mtl_uv_transform(opts: dict[str, list[str]]) -> tuple[float, float, float, float] | None:
    """MTL ``-s`` scale and ``-o`` offset of texture coordinates: (su, sv, ou, ov) or None."""
    try:
        s = [float(x) for x in opts.get("-s", [])]
        o = [float(x) for x in opts.get("-o", [])]
    except ValueError:
        return None
    t = (s[0] if s else 1.0, s[1] if len(s) > 1 else 1.0, o[0] if o else 0.0, o[1] if len(o) > 1 else 0.0)
    return None if t == (1.0, 1.0, 0.0, 0.0) else t


def _obj_texture(m: _MtlMaterial, fname: str, root: Path | None) -> Image.Image:
    rel = fname.replace("\\", "/")
    where = f"{m.source}: texture '{fname}'"
    real = locate(Path(rel), root, where, base=m.folder, must_exist=False)
    if not real.is_file():  # exporters often write absolute paths of the author's machine
        alt = locate(Path(Path(rel).name), root, where, base=m.folder, must_exist=False)
        if not alt.is_file():
            raise AssetError(f"{where} not found (looked in {m.folder})")
        real = alt
    return decode_image(read_bytes_of(real, where), where)


def _matte(img: Image.Image, channel: str) -> np.ndarray:
    """The opacity an MTL ``map_d`` image gives (``-imfchan`` r, g, b, m = matte, l = luminance)."""
    channel = channel.lower()
    rgba = rgba_array(img)
    if channel in ("r", "g", "b"):
        return rgba[..., "rgb".index(channel)].copy()
    has_alpha = img.mode in ("RGBA", "LA", "PA", "La", "RGBa") or (img.mode == "P" and "transparency" in img.info)
    if channel == "m" and has_alpha:
        return rgba[..., 3].copy()
    return np.asarray(Image.fromarray(rgba[..., :3], "RGB").convert("L"))
