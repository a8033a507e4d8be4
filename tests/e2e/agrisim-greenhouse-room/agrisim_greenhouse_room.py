"""The ``greenhouse`` room: a gravel floor 8 m square, the cell's obstacles as plain boxes and
cylinders at their sizes and poses (trimesh's primitives), ``benches`` more benches in a row
beside the table (their positions drawn from the run's seed), the plant on its soil, and
daylight: one large area light high above."""

from __future__ import annotations

import numpy as np
import trimesh
from pydantic import Field

from agrisim import BackendSpec, Options, hookimpl
from agrisim.interfaces import Room
from agrisim.robot.cell import Box, place_plant
from agrisim.scene.model import Light, Material, Mesh, Plant, Scene

GRAVEL = Material("gravel", color=(0.45, 0.43, 0.40, 1.0), roughness=1.0)
BENCH = Material("bench", color=(0.60, 0.62, 0.64, 1.0), roughness=0.6)


class GreenhouseOptions(Options):
    benches: int = Field(default=3, ge=0, le=20)
    """Benches beside the cell's table."""


def _mesh(name: str, shape: trimesh.Trimesh, material: Material) -> Mesh:
    return Mesh(name, shape.vertices, shape.faces, [material], np.zeros(len(shape.faces), np.int32))


class Greenhouse(Room):
    def scene(self, plant: Plant, *, seed: int, labels: str) -> Scene:
        placed = place_plant(plant, self.cell, labels)
        floor = trimesh.creation.box((8.0, 8.0, 0.02), trimesh.transformations.translation_matrix((0, 0, -0.01)))
        meshes = [_mesh("gravel", floor, GRAVEL)]
        for ob in self.cell.obstacles:
            if ob.name in ("floor", "plant_keepout"):
                continue
            if isinstance(ob, Box):
                shape = trimesh.creation.box(ob.size, ob.world_T)
            else:
                shape = trimesh.creation.cylinder(ob.radius, ob.height, sections=32, transform=ob.world_T)
            meshes.append(_mesh(ob.name, shape, BENCH))
        rng = np.random.default_rng(seed)
        for i in range(self.options.benches):
            at = trimesh.transformations.translation_matrix((rng.uniform(-3.0, 3.0), 2.5, 0.4))
            meshes.append(_mesh(f"bench_{i}", trimesh.creation.box((1.2, 0.6, 0.8), at), BENCH))
        if placed.points is None:  # (a plant drawn as points is drawn by its points)
            meshes.append(placed.mesh)
        sky = Light("sky", "area", np.array([0.0, 0.0, 6.0]), np.array([0.0, 0.0, -1.0]), (1.0, 0.98, 0.95), 12.0, 2.0)
        return Scene(
            meshes=meshes, lights=[sky], labels=placed.labels, plant="plant", points=placed.points, source=placed.source
        )


@hookimpl
def agrisim_rooms() -> list[BackendSpec]:
    return [
        BackendSpec(
            name="greenhouse",
            factory=Greenhouse,
            description="a greenhouse: gravel floor, benches, daylight from above",
            options_model=GreenhouseOptions,
        )
    ]
