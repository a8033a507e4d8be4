"""The turntable cell: a round table that turns (the stage) with the pot on it, and the cameras
``c1``, ``c2``, ... on a column on its +x side (:mod:`.urdf`: one-joint robots whose joint is
the stage's angle). The routine: the grid's columns are the stage's angles over a whole turn,
its levels the cameras (from the first); at each step every camera shoots at the same angle, as
a station whose stage stops for all its cameras."""

from __future__ import annotations

import math

import numpy as np

from agrisim.config import CellConfig, RoutineConfig, parse_grid
from agrisim.interfaces import Rig
from agrisim.plugins.rigs.turntable import TurntableOptions
from agrisim.plugins.rigs.turntable.urdf import COLUMN_ABOVE, COLUMN_LIFT, STAGE_JOINT, camera_urdf
from agrisim.robot.cell import Arm, Box, Cell, Cylinder, Obstacle
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.setpoints import Setpoint
from agrisim.robot.urdf import CAMERA_FRAME
from agrisim.scene.transforms import translation

__all__ = ["TurntableRig", "stage_angles"]


def stage_angles(count: int) -> np.ndarray:
    """``count`` stage angles over a whole turn, radians, from 0."""
    return np.arange(count) * (2.0 * math.pi / count)


class TurntableRig(Rig):
    """The plant on a turning stage and the cameras on a column (``[rig.turntable]``); ``[cell]``
    sizes the table's height, the pot and the keep-out; ``[cell] arms`` does not apply."""

    options: TurntableOptions

    def __init__(self, settings: CellConfig, options: TurntableOptions | None = None) -> None:
        super().__init__(settings, options if options is not None else TurntableOptions())
        self.notes: list[str] = []

    def tilts(self) -> list[float]:
        """Each camera's downward tilt, radians: as given, else aimed at ``[routine]
        aim_height`` above the stage's centre."""
        o = self.options
        if o.tilts_deg is not None:
            return [math.radians(t) for t in o.tilts_deg]
        aim = RoutineConfig().aim_height
        return [math.atan2(h - aim, o.distance) for h in o.heights]

    def cell(self) -> Cell:
        cfg, o = self.settings, self.options
        top = cfg.table_height
        centre = np.array([0.0, 0.0, top])
        obstacles: list[Obstacle] = [
            Box("floor", (6.0, 6.0, 0.02), translation(0.0, 0.0, -0.01)),
            # the stage: a round table, the same at every angle (what turns with the plant
            # must look the same from every camera position for the orbit to be exact)
            Cylinder("table", o.stage_radius, top, translation(0.0, 0.0, top / 2)),
            Cylinder("pot", cfg.pot_radius, cfg.pot_height, translation(0.0, 0.0, top + cfg.pot_height / 2)),
        ]
        if cfg.keepout_radius > 0 and cfg.keepout_height > 0:
            keepout = min(cfg.keepout_radius, o.distance - 0.05)
            obstacles.append(
                Cylinder(
                    "plant_keepout", keepout, cfg.keepout_height, translation(0.0, 0.0, top + cfg.keepout_height / 2)
                )
            )
        speed = math.radians(o.stage_speed_deg_s)
        column = (-top + COLUMN_LIFT, max(o.heights) + COLUMN_ABOVE)  # (its foot clear of the floor's checks)
        arms = []
        for i, (height, tilt) in enumerate(zip(o.heights, self.tilts(), strict=True)):
            name = f"c{i + 1}"
            urdf = camera_urdf(name, o.distance, height, tilt, column=column if i == 0 else None, speed=speed)
            arms.append(
                Arm(
                    name=name,
                    urdf=urdf,
                    world_T_base=translation(*centre),
                    stand="table",
                    joints=(STAGE_JOINT,),
                    camera_frame=CAMERA_FRAME,
                    home=(0.0,),
                    accelerations=(math.radians(o.stage_acceleration_deg_s2),),
                )
            )
        if not self.notes:
            self.notes.append(
                f"turntable with {len(arms)} camera(s) {o.distance:.2f} m from the stage's axis at "
                + ", ".join(f"{h:.2f} m" for h in o.heights)
                + f" above its top; the stage turns at {o.stage_speed_deg_s:g} deg/s"
            )
        return Cell(arms=tuple(arms), obstacles=tuple(obstacles), plant_center=centre)

    def setpoints(self, cell: Cell, routine: RoutineConfig) -> dict[str, list[Setpoint]]:
        """The grid's columns are the stage's angles over a whole turn; its levels the cameras
        used, the first ones (more levels than cameras: all of them). Each camera's poses are its own
        forward kinematics at those angles: reachable by construction."""
        levels, columns = parse_grid(routine.setpoints)
        if levels > len(cell.arms):
            self.notes.append(
                f"the grid's {levels} levels ask for more cameras than the {len(cell.arms)} on the column: "
                f"all {len(cell.arms)} shoot at each of {columns} stage angles"
            )
        angles = stage_angles(columns)
        out: dict[str, list[Setpoint]] = {}
        for arm in cell.arms[:levels]:
            kin = ArmKinematics(arm)
            out[arm.name] = [Setpoint(arm.name, k, kin.fk(np.array([a]))) for k, a in enumerate(angles)]
        return out
