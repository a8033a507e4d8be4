"""The paper's cell built from ``[cell]``: arms ``r1`` (+x side) and ``r2`` (-x side) on stands,
facing the plant table and its pot; their default viewpoints are the paper's hemisphere
(:func:`hemisphere`)."""

from __future__ import annotations

import numpy as np

from agrisim.config import CellConfig, RoutineConfig, parse_grid
from agrisim.interfaces import Rig
from agrisim.robot.cell import Arm, Box, Cell, Cylinder, Obstacle
from agrisim.robot.setpoints import Setpoint
from agrisim.robot.urdf import ur10_with_camera
from agrisim.scene.transforms import look_at, translation, yaw_matrix

__all__ = ["PaperRig", "build_cell", "hemisphere", "plant_table"]


def plant_table(cfg: CellConfig) -> list[Obstacle]:
    """The floor, the square plant table, the pot on it and the plant's keep-out (where
    ``[cell]`` gives it one), as ``[cell]`` sizes them: what the paper's cell and the gantry's
    stand around."""
    table_top = cfg.table_height
    obstacles: list[Obstacle] = [
        Box("floor", (6.0, 6.0, 0.02), translation(0.0, 0.0, -0.01)),
        Box("table", (cfg.table_size, cfg.table_size, table_top), translation(0.0, 0.0, table_top / 2)),
        Cylinder("pot", cfg.pot_radius, cfg.pot_height, translation(0.0, 0.0, table_top + cfg.pot_height / 2)),
    ]
    if cfg.keepout_radius > 0 and cfg.keepout_height > 0:
        obstacles.append(
            Cylinder(
                "plant_keepout",
                cfg.keepout_radius,
                cfg.keepout_height,
                translation(0.0, 0.0, table_top + cfg.keepout_height / 2),
            )
        )
    return obstacles


def build_cell(cfg: CellConfig) -> Cell:
    """The paper's cell: arms ``r1`` (+x side) and ``r2`` (-x side), facing the plant."""
    urdf = ur10_with_camera()
    center = np.array([0.0, 0.0, cfg.table_height])
    obstacles = plant_table(cfg)
    arms = []
    for i, side in enumerate((1.0, -1.0)[: cfg.arms]):
        name = f"r{i + 1}"
        stand = f"{name}_stand"
        x = side * cfg.arm_distance
        obstacles.append(
            Box(stand, (cfg.stand_size, cfg.stand_size, cfg.stand_height), translation(x, 0.0, cfg.stand_height / 2))
        )
        # UR10 at zero joints stretches along its base +x: turn each base to face the plant.
        world_T_base = translation(x, 0.0, cfg.stand_height) @ yaw_matrix(np.pi if side > 0 else 0.0)
        arms.append(Arm(name=name, urdf=urdf, world_T_base=world_T_base, stand=stand))
    return Cell(arms=tuple(arms), obstacles=tuple(obstacles), plant_center=center)


def hemisphere(cell: Cell, cfg: RoutineConfig) -> dict[str, list[Setpoint]]:
    """The paper's routine: per arm, L levels x C columns on its half of the hemisphere.

    ``phi`` is the polar angle from the zenith, ``theta`` the azimuth across the arm's half
    (0..pi spans the half facing that arm). Cameras look at the point ``aim_height`` above the
    centre (the plant's middle rather than its pot). Levels run top to bottom and columns alternate
    direction (snake order), so consecutive setpoints are neighbours.
    """
    levels, columns = parse_grid(cfg.setpoints)
    phis = np.radians(np.linspace(*cfg.phi_deg, levels))
    thetas = np.radians(np.linspace(*cfg.theta_deg, columns))
    center = cell.plant_center
    aim = np.array([0.0, 0.0, cfg.aim_height])
    out: dict[str, list[Setpoint]] = {}
    for arm in cell.arms:
        # Azimuth 0..pi is turned so that the half faces the arm's base.
        base = arm.world_T_base[:3, 3] - center
        facing = np.arctan2(base[1], base[0])
        points = []
        for i, phi in enumerate(phis):
            row = thetas if i % 2 == 0 else thetas[::-1]
            for theta in row:
                azimuth = facing - np.pi / 2 + theta
                direction = np.array([np.sin(phi) * np.cos(azimuth), np.sin(phi) * np.sin(azimuth), np.cos(phi)])
                points.append(look_at(center + cfg.radius * direction, center + aim))
        out[arm.name] = [Setpoint(arm.name, k, T) for k, T in enumerate(points)]
    return out


class PaperRig(Rig):
    """The paper's two UR10s (``[cell] arms = 1``: the +x one alone) and its hemisphere."""

    def cell(self) -> Cell:
        return build_cell(self.settings)

    def setpoints(self, cell: Cell, routine: RoutineConfig) -> dict[str, list[Setpoint]]:
        return hemisphere(cell, routine)
