"""agrisim's plant file formats: glTF 2.0 (``.glb``, ``.gltf``) and OBJ (``.obj`` with its
``.mtl``) meshes (:mod:`.plant_asset`, :mod:`.gltf`, :mod:`.obj`), and PLY and PCD point
clouds (:mod:`.point_cloud`), each a reader of the ``format`` kind; :mod:`.scene_glb` reads a
run's saved scene back."""

from __future__ import annotations

from agrisim import BackendSpec, hookimpl
from agrisim.kinds import lazy


@hookimpl
def agrisim_plant_formats() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="gltf",
            factory=lazy("agrisim.plugins.formats.readers:GltfFormat"),
            description="glTF 2.0 meshes (.glb, .gltf): textures with alpha, label textures or material labels, "
            "the node graph's transforms; agrisim's own GLB with its labels and leaf instances",
            limits="one UV set per material; no skins, morph targets or animations",
        ),
        BackendSpec(
            name="obj",
            factory=lazy("agrisim.plugins.formats.readers:ObjFormat"),
            description="Wavefront OBJ meshes (.obj with its .mtl and texture images): map_Kd, map_d opacity",
            limits="y up unless [plant_file] up says z; Tr is ignored (exporters disagree on its sign)",
        ),
        BackendSpec(
            name="points",
            factory=lazy("agrisim.plugins.formats.readers:PointFormat"),
            description="point clouds (.ply without faces, .pcd): colours, label and instance properties",
        ),
    ]
