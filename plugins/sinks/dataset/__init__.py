"""The dataset sink: the run directory's files, written as the run goes (DESIGN.md's
``dataset`` sink). Every run has it, whatever plugins are chosen: ``resume``, ``recon``, the
exports and ``compare`` read what it writes. :mod:`.writer` writes the views, ``cameras.json``,
``run.json``, trajectories and link poses; :mod:`.glb` and :mod:`.scene_glb` the plant and the
scene as glTF; :mod:`.point_cloud` a point plant as PLY; :mod:`.reconstruction` the clouds and
``metrics.json``."""

from __future__ import annotations

from agrisim import BackendSpec, hookimpl
from agrisim.kinds import lazy

#: its entry point, which every run loads (:func:`agrisim.registry.with_own_plugins`)
ENTRY_POINT = "sink-dataset"


@hookimpl
def agrisim_sinks() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="dataset",
            factory=lazy("agrisim.plugins.sinks.dataset.writer:DatasetWriter"),
            description="the run directory: rgb/, labels/, depth/, instances/ as PNG, cameras.json, run.json, "
            "trajectories, link poses, the plant and scene as glTF, clouds and metrics.json",
        )
    ]
