"""The reconstruction's files in a run directory: ``clouds/<label>.ply`` (the merged clouds, with
their colours), the reconstructor's meshes and files, and ``metrics.json``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from agrisim.data import Cloud, Reconstruction
from agrisim.evaluation.session import vertex_colors
from agrisim.files import layout
from agrisim.files.atomic import write_bytes, write_json, write_through


def output_files(out_dir: Path, result: Reconstruction) -> list[Path]:
    """The files :func:`write_reconstruction` writes for ``result``."""
    return (
        [layout.cloud(out_dir, name) for name in result.clouds]
        + [layout.surface(out_dir, name) for name in result.meshes]
        + [out_dir / layout.METRICS_JSON]
    )


def cloud_ply(cloud: Cloud) -> bytes:
    """A cloud as binary PLY (float64 x, y, z and uchar red, green, blue): the very bytes
    Open3D's ``write_point_cloud`` writes, without needing Open3D (a GPU machine's minimal
    install writes clouds too)."""
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment Created by Open3D\n"
        f"element vertex {len(cloud.points)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    rows = np.empty(len(cloud.points), [("xyz", "<f8", 3), ("rgb", "u1", 3)])
    rows["xyz"], rows["rgb"] = cloud.points, cloud.colors
    return header.encode() + rows.tobytes()


def write_reconstruction(out_dir: Path, result: Reconstruction, metrics: dict[str, Any]) -> None:
    """``clouds/<label>.ply`` (binary PLY, colours), ``clouds/<label>_mesh.ply``, the
    reconstructor's own files and ``metrics.json``, each written atomically."""
    write_clouds(out_dir, result)
    for relative, data in result.files.items():
        write_bytes(out_dir / relative, data)
    # a replaced reconstructor folder keeps nothing of the old result (e.g. another split's views)
    written = {out_dir / relative for relative in result.files}
    for folder in {Path(relative).parts[0] for relative in result.files}:
        for stale in [p for p in (out_dir / folder).rglob("*") if p.is_file() and p not in written]:
            stale.unlink()
    write_json(out_dir / layout.METRICS_JSON, metrics)


def write_clouds(out_dir: Path, result: Reconstruction, plant: str = "") -> None:
    """``result``'s clouds and surfaces (``clouds/<label>.ply``, ``clouds/<label>_mesh.ply``;
    a bench's ``plant``'s in ``clouds/<plant>/``), each written atomically."""
    (out_dir / layout.CLOUDS / plant).mkdir(parents=True, exist_ok=True)
    for name, cloud in result.clouds.items():
        # (an empty cloud too: Open3D refuses to write one, readers accept it)
        write_bytes(layout.cloud(out_dir, name, plant), cloud_ply(cloud) if len(cloud.points) else _EMPTY_PLY)
    if result.meshes:
        import open3d as o3d
    for name, mesh in result.meshes.items():
        if len(mesh.vertices) == 0:
            write_bytes(layout.surface(out_dir, name, plant), _EMPTY_PLY)
            continue
        tm = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(mesh.vertices), o3d.utility.Vector3iVector(mesh.triangles)
        )
        tm.vertex_colors = o3d.utility.Vector3dVector(vertex_colors(mesh).astype(np.float64) / 255.0)

        def write(tmp: str, g: o3d.geometry.TriangleMesh = tm) -> bool:
            # Open3D's stub asks for an os.PathLike; its binding takes a str as well
            return o3d.io.write_triangle_mesh(tmp, g, write_ascii=False)  # type: ignore[arg-type]

        write_through(layout.surface(out_dir, name, plant), write)


_EMPTY_PLY = (
    b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty double x\nproperty double y\n"
    b"property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
)


# -------------------------------------------------------------------- from a saved run
