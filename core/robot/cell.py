"""The robot cell as plain data: arms on stands, the plant table, the pot.

One backend-free description, built by the run's rig (:class:`agrisim.interfaces.Rig`), that
every physics backend, planner check and sink builds from (Kubric's pattern: one scene model). World frame: z up, origin on the floor
below the plant; the pot's centre on the table top is the routine's hemisphere centre.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from agrisim.robot.urdf import ARM_JOINTS, CAMERA_FRAME
from agrisim.scene.model import BenchPlant, Label, LabelTable, Mesh, Plant, PointSet
from agrisim.scene.transforms import translation

SOIL_INSET = 0.015
"""Depth of the soil surface below the pot's rim, m (capped at a third of the pot's height)."""
PLANT_LABEL = Label(1, "plant", (0, 255, 0))
"""The single plant label of ``labels="plant"``."""


@dataclass(frozen=True)
class Box:
    """An axis-aligned (in its own frame) box: ``size`` are full extents, m."""

    name: str
    size: tuple[float, float, float]
    world_T: np.ndarray


@dataclass(frozen=True)
class Cylinder:
    """A z-aligned cylinder centred at ``world_T``'s origin."""

    name: str
    radius: float
    height: float
    world_T: np.ndarray


Obstacle = Box | Cylinder


@dataclass(frozen=True)
class Arm:
    """One arm: its URDF (with camera), where its base sits, and its arm joints."""

    name: str
    urdf: str
    world_T_base: np.ndarray
    stand: str  # the obstacle its base rests on (touching it is not a collision)
    joints: tuple[str, ...] = ARM_JOINTS
    camera_frame: str = CAMERA_FRAME
    home: tuple[float, ...] = (0.0, -1.9, 1.9, -1.57, -1.57, 0.0)
    #: each joint's acceleration limit, rad/s^2 or m/s^2, where the machine has its own (a stage's,
    #: a gantry's axes'); a run keeps within it and ``[motion] max_acceleration`` both
    accelerations: tuple[float, ...] | None = None


@dataclass(frozen=True)
class Cell:
    """Arms, static obstacles, and the plant centre."""

    arms: tuple[Arm, ...]
    obstacles: tuple[Obstacle, ...]
    plant_center: np.ndarray
    #: the plants of a bench (their pots ``pot_01``...; :func:`agrisim.bench.bench_cell`), else empty
    bench: tuple[BenchPlant, ...] = ()

    def arm(self, name: str) -> Arm:
        for arm in self.arms:
            if arm.name == name:
                return arm
        raise KeyError(f"no arm named {name!r}; arms are {[a.name for a in self.arms]}")

    @property
    def arm_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.arms)


def soil_pose(cell: Cell) -> np.ndarray:
    """``world_T_plant``: the plant frame on the soil surface (centre of the pot, z up); a
    bench's frame: on its soil, below the cell's plant centre."""
    pot = next((ob for ob in cell.obstacles if ob.name in ("pot", "pot_01")), None)
    if pot is None:
        return translation(*cell.plant_center)
    assert isinstance(pot, Cylinder)
    soil = pot.world_T @ translation(0.0, 0.0, pot.height / 2 - min(SOIL_INSET, pot.height / 3))
    return translation(cell.plant_center[0], cell.plant_center[1], soil[2, 3]) if cell.bench else soil


@dataclass
class PlacedPlant:
    """A run's plant on the soil of its cell, as every room draws it: its mesh in world
    coordinates named ``plant`` (every organ one ``plant`` label with ``labels="plant"``, the
    plant's own table with ``"organs"``), its points where it is drawn as points."""

    mesh: Mesh
    labels: LabelTable
    points: PointSet | None

    @property
    def drawn(self) -> np.ndarray:
        """N x 3: the points of what is drawn (the points of a point plant, else its vertices)."""
        return self.points.positions if self.points is not None else self.mesh.vertices

    @property
    def source(self) -> Mesh | None:
        """The mesh a point plant was sampled from (its truth, not drawn), else None."""
        return self.mesh if self.points is not None and len(self.mesh.faces) else None


def place_plant(plant: Plant, cell: Cell, labels: str) -> PlacedPlant:
    """``plant`` moved from its own frame onto the cell's soil (:func:`soil_pose`), its labels as
    the run's ``labels`` mode (``plant`` or ``organs``) says."""
    if labels not in ("plant", "organs"):
        raise ValueError(f"labels must be 'plant' or 'organs', got {labels!r}")
    world_T_plant = soil_pose(cell)
    mesh = plant.mesh
    if labels == "plant":
        lut = np.ones(256, np.uint8)
        lut[0] = 0
        materials = [
            dataclasses.replace(m, labels=None if m.labels is None else lut[m.labels], label=int(lut[m.label]))
            for m in mesh.materials
        ]
        table = LabelTable([Label(0, "background", (0, 0, 0)), PLANT_LABEL])
    else:
        materials = list(mesh.materials)
        table = LabelTable(list(plant.labels.labels))
    V = mesh.vertices @ world_T_plant[:3, :3].T + world_T_plant[:3, 3]
    placed = dataclasses.replace(mesh, name="plant", vertices=V, materials=materials)
    points = None
    if plant.points is not None:  # drawn as points; its mesh (if any) is the truth, not drawn
        points = plant.points.transformed(world_T_plant)
        if labels == "plant":
            points.labels = (points.labels > 0).astype(np.uint8)
    return PlacedPlant(placed, table, points)
