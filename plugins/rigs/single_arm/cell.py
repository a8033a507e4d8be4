"""The single-arm cell: the plant table and pot as the paper has them, one arm ``r1`` on a
stand on the +x side facing the plant, sized by its reach (:mod:`.layout`); its viewpoints are
the paper's hemisphere (:func:`agrisim.plugins.rigs.paper.cell.hemisphere`) at the rig's radius."""

from __future__ import annotations

import dataclasses
import math
from functools import cached_property
from pathlib import Path

import numpy as np

from agrisim.config import CellConfig, RoutineConfig
from agrisim.errors import UserError
from agrisim.interfaces import Rig
from agrisim.plugins.rigs.paper.cell import hemisphere
from agrisim.plugins.rigs.single_arm import SingleArmOptions
from agrisim.plugins.rigs.single_arm.layout import (
    BASE_CLEARANCE,
    RADIUS_SHARE,
    Reach,
    check_home,
    check_reach,
    choose_layout,
    home_pose,
    measure_reach,
)
from agrisim.plugins.rigs.single_arm.robots import ROBOTS, USER_MOUNT
from agrisim.plugins.rigs.single_arm.urdf_camera import ArmDescription, with_camera
from agrisim.robot.cell import Arm, Box, Cell, Cylinder, Obstacle
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.setpoints import Setpoint
from agrisim.scene.transforms import translation, yaw_matrix

__all__ = ["ARM", "MIN_JOINTS", "SingleArmRig"]

#: the arm's name (frames r1_000, r1_001, ...)
ARM = "r1"
#: a camera pose (position and orientation) needs this many joints
MIN_JOINTS = 6
#: gap between the stand and the table, m
TABLE_GAP = 0.03
#: how far below shoulder-at-aim-height a stand is tried when no layout reaches every probe, m
STAND_DROPS = (0.0, 0.15, 0.3)
#: how far inside the hemisphere's lowest ring the table's edge stays, m: a camera there looks
#: at the plant from just above the table top, and the wrist behind it (a Panda's hand is 10 cm
#: deep) must pass beyond the edge rather than into the top
RING_CLEARANCE = 0.1


class SingleArmRig(Rig):
    """One arm (``[rig.single-arm]``) beside the plant; ``[cell] arms`` does not apply.

    ``notes`` holds the line ``agrisim run`` prints about the layout it chose."""

    options: SingleArmOptions

    def __init__(self, settings: CellConfig, options: SingleArmOptions | None = None) -> None:
        super().__init__(settings, options if options is not None else SingleArmOptions())
        self.notes: list[str] = []
        #: the hemisphere's radius, m (chosen with the cell)
        self.radius = 0.0

    @property
    def robot(self) -> str:
        """The arm's name as a run reports it: a built-in's, or the user's URDF file's."""
        return self.options.urdf.name if self.options.urdf is not None else self.options.robot

    @cached_property
    def description(self) -> ArmDescription:
        """The arm's URDF with its camera, and its joints (refused below :data:`MIN_JOINTS`)."""
        o = self.options
        if o.urdf is not None:
            xyz, rpy = USER_MOUNT
            desc = with_camera(Path(o.urdf), str(o.camera_link), o.camera_xyz or xyz, o.camera_rpy or rpy)
        else:
            robot = ROBOTS[o.robot]
            path = robot.path()
            desc = with_camera(path, robot.mount, o.camera_xyz or robot.xyz, o.camera_rpy or robot.rpy)
        if len(desc.joints) < MIN_JOINTS:
            raise UserError(
                f"rig single-arm: {self.robot} has {len(desc.joints)} joints from {desc.root} to {desc.mount} "
                f"({', '.join(desc.joints)}); a camera pose needs at least {MIN_JOINTS}; robots: "
                + ", ".join(n for n in ROBOTS if n != "so101")
            )
        return desc

    @cached_property
    def _kinematics(self) -> ArmKinematics:
        """The arm's kinematics with its base at the origin."""
        desc = self.description
        arm = Arm(ARM, desc.urdf, np.eye(4), f"{ARM}_stand", joints=desc.joints, home=(0.0,) * len(desc.joints))
        return ArmKinematics(arm)

    @cached_property
    def reach(self) -> Reach:
        """What the arm's camera reaches from its shoulder."""
        return measure_reach(self._kinematics)

    def _stand_heights(self) -> list[float]:
        """The stand heights a layout is looked for on: the user's, else the one that puts the
        shoulder level with the point the cameras aim at, then lower ones (:data:`STAND_DROPS`)."""
        cfg, o = self.settings, self.options
        if o.stand_height is not None:
            return [o.stand_height]
        level = cfg.table_height + RoutineConfig().aim_height - float(self.reach.shoulder[2])
        return [max(level - drop, 0.0) for drop in STAND_DROPS if drop == 0.0 or level - drop > 0.0]

    def _layout_cell(self, distance: float, radius: float, stand_height: float) -> Cell:
        """The cell with the base ``distance`` from the plant centre on a stand ``stand_height``
        tall and a keep-out that fits a hemisphere of ``radius``; the arm's home its zero joints
        within limits."""
        cfg, desc = self.settings, self.description
        stand_size = min(cfg.stand_size, max(0.12, 0.4 * distance))
        ring = radius * math.sin(math.radians(RoutineConfig().phi_deg[1]))
        table_size = min(
            cfg.table_size,
            2 * (distance - stand_size / 2 - TABLE_GAP),
            max(2 * (ring - RING_CLEARANCE), 2 * cfg.pot_radius + 0.04),
        )
        if table_size < 2 * cfg.pot_radius:
            raise UserError(
                f"rig single-arm: at distance {distance:.2f} m the arm's stand leaves no room for the pot "
                f"(radius {cfg.pot_radius} m); set a larger rig.single-arm.distance"
            )
        top = cfg.table_height
        obstacles: list[Obstacle] = [
            Box("floor", (6.0, 6.0, 0.02), translation(0.0, 0.0, -0.01)),
            Box("table", (table_size, table_size, top), translation(0.0, 0.0, top / 2)),
            Cylinder("pot", cfg.pot_radius, cfg.pot_height, translation(0.0, 0.0, top + cfg.pot_height / 2)),
            Box(f"{ARM}_stand", (stand_size, stand_size, stand_height), translation(distance, 0.0, stand_height / 2)),
        ]
        # the keep-out cylinder stays clear of the hemisphere's top viewpoints (their camera bodies)
        keepout = min(cfg.keepout_radius, 0.45 * radius)
        if keepout > 0 and cfg.keepout_height > 0:
            obstacles.append(
                Cylinder(
                    "plant_keepout", keepout, cfg.keepout_height, translation(0.0, 0.0, top + cfg.keepout_height / 2)
                )
            )
        # the base's x axis towards the plant (the UR10 stretches along it at zero joints)
        world_T_base = translation(distance, 0.0, stand_height) @ yaw_matrix(np.pi)
        kin = self._kinematics
        home = tuple(float(v) for v in np.clip(np.zeros(kin.dof), kin.lower, kin.upper))
        arm = Arm(ARM, desc.urdf, world_T_base, f"{ARM}_stand", joints=desc.joints, home=home)
        return Cell(arms=(arm,), obstacles=tuple(obstacles), plant_center=np.array([0.0, 0.0, top]))

    @cached_property
    def _cell(self) -> Cell:
        cfg, o = self.settings, self.options
        desc, reach = self.description, self.reach
        aim = RoutineConfig().aim_height
        stand_height = self._stand_heights()[0]
        if o.distance is not None and o.radius is not None:
            distance, radius = o.distance, o.radius
        elif o.distance is not None:  # the radius a share of the reach, as far as it goes
            distance, radius = o.distance, min(RADIUS_SHARE * reach.radius, max(o.distance - BASE_CLEARANCE, 0.06))
        else:

            def above(stand: float) -> float:
                return stand + float(reach.shoulder[2]) - cfg.table_height

            distance, radius, stand_height = choose_layout(
                self._layout_cell, reach, o.radius, self._stand_heights(), above, aim, self.robot
            )
        self.radius = radius
        cell = self._layout_cell(distance, radius, stand_height)
        arm = cell.arms[0]
        kin = ArmKinematics(arm)
        if o.home is not None:
            check_home(cell, arm, kin, o.home)
            home = tuple(float(v) for v in o.home)
        else:
            home = tuple(float(v) for v in home_pose(cell, arm, kin, radius, aim))
        self.notes.append(
            f"{self.robot} on the single-arm rig ({len(desc.joints)} joints, camera reach {reach.radius:.2f} m): "
            f"distance {distance:.2f} m{'' if o.distance is not None else ' (from its reach)'}, "
            f"radius {radius:.2f} m{'' if o.radius is not None else ' (from its reach)'}, stand {stand_height:.2f} m"
        )
        return dataclasses.replace(cell, arms=(dataclasses.replace(arm, home=home),))

    def cell(self) -> Cell:
        return self._cell

    def setpoints(self, cell: Cell, routine: RoutineConfig) -> dict[str, list[Setpoint]]:
        self.cell()  # the radius is chosen with the cell
        points = hemisphere(cell, routine.model_copy(update={"radius": self.radius}))
        for arm in cell.arms:
            shoulder = arm.world_T_base[:3, :3] @ self.reach.shoulder + arm.world_T_base[:3, 3]
            check_reach(shoulder, self.reach, [sp.world_T_camera[:3, 3] for sp in points.get(arm.name, [])], self.robot)
        return points
