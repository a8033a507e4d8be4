"""Makes ``plugins/render/arm_meshes_ur10.npz`` again: the cell's arm (the UR10 with its camera,
:func:`agrisim.robot.urdf.ur10_with_camera`) decimated by Open3D to the renderers' default
``arm_triangles``, which agrisim ships so that the default run draws the arms it always drew
without Open3D installed (``agrisim.plugins.render.arm_visuals``). Needs Open3D (the dev environment has it).

Run it after the mesh files (example-robot-data), trimesh, Open3D or the default budget change;
``tests/unit/test_arm_visuals.py`` fails until then. The same inputs give the same bytes.

    python scripts/arm_meshes.py
"""

from __future__ import annotations

import hashlib
import time
from importlib import metadata

import numpy as np

from agrisim.plugins.render import arm_visuals as visuals
from agrisim.plugins.render.mitsuba.options import MitsubaOptions
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.robot.urdf import ur10_with_camera


def open3d_decimate(v: np.ndarray, f: np.ndarray, target: float) -> tuple[np.ndarray, np.ndarray]:
    """Quadric edge-collapse decimation to about ``target`` triangles: Open3D's, as
    ``agrisim.plugins.render.arm_visuals`` decimated every arm before these meshes were shipped."""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v), o3d.utility.Vector3iVector(f.astype(np.int32)))
    mesh = mesh.simplify_quadric_decimation(max(int(target), 4))
    mesh.remove_degenerate_triangles()
    mesh.remove_unreferenced_vertices()
    return np.asarray(mesh.vertices, float), np.asarray(mesh.triangles, np.int64)


def main() -> None:
    budget = RaycastOptions().arm_triangles
    # one file serves both renderers only while their defaults agree
    assert MitsubaOptions().arm_triangles == budget, "the renderers' default arm_triangles differ"
    urdf = ur10_with_camera()
    inputs = visuals.visual_inputs(urdf)
    if not inputs.complete:
        raise SystemExit(f"a mesh file of the UR10 is missing: {inputs.meshes}")
    t0 = time.perf_counter()
    links = visuals._link_meshes(urdf, budget, decimate=open3d_decimate)
    made = time.perf_counter() - t0
    meta = {
        "urdf_sha256": inputs.urdf_sha256,
        "meshes": [list(m) for m in inputs.meshes],
        "max_triangles": budget,
        "open3d": metadata.version("open3d"),
        "trimesh": metadata.version("trimesh"),
        "made_by": "scripts/arm_meshes.py",
    }
    path = visuals.PRECOMPUTED
    before = path.read_bytes() if path.exists() else b""
    visuals.write_precomputed(path, links, meta)
    after = path.read_bytes()
    triangles = sum(len(lm.mesh.faces) for lm in links)
    state = "unchanged" if before == after else "written"
    print(f"{path}: {state}, {len(after) / 1e3:.0f} kB, {triangles} triangles in {len(links)} links")
    print(
        f"  loading and decimating with Open3D {meta['open3d']}: {made:.2f} s; sha256 {hashlib.sha256(after).hexdigest()}"
    )


if __name__ == "__main__":
    main()
