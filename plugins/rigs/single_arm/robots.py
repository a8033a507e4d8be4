"""The arms ``[rig.single-arm] robot`` names: example-robot-data's URDFs, each with the link
its camera mounts on and where on that link the camera body sits.

Mount offsets put the camera body's centre half a body (2.5 cm) beyond whatever the tool link
carries (a flange, a closed gripper's fingertips), its +x axis (the optical axis) pointing out
of the tool, so that no part of the arm stands in front of the lens.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from agrisim.robot.urdf import robot_data_share

#: the tool's +z axis out of the tool (ROS's tool0 convention): the camera body's x turned onto it
Z_OUT = (0.0, -math.pi / 2, 0.0)
X_OUT = (0.0, 0.0, 0.0)
#: a user URDF's default mount: on the camera link, pointing along its +z
USER_MOUNT = ((0.0, 0.0, 0.025), Z_OUT)


@dataclass(frozen=True)
class Robot:
    """A built-in arm: its URDF under example-robot-data's ``robots`` folder, the link its
    camera mounts on, and the camera body's default pose on that link (xyz in m, rpy in rad)."""

    urdf: str
    mount: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]

    def path(self) -> Path:
        """The URDF file in the installed example-robot-data."""
        return robot_data_share() / "example-robot-data" / "robots" / self.urdf


ROBOTS: dict[str, Robot] = {
    # ee_link's x points out of the flange; the UR10's is the paper rig's camera exactly
    "ur3": Robot("ur_description/urdf/ur3_robot.urdf", "ee_link", (0.025, 0.0, 0.0), X_OUT),
    "ur5": Robot("ur_description/urdf/ur5_robot.urdf", "ee_link", (0.025, 0.0, 0.0), X_OUT),
    "ur10": Robot("ur_description/urdf/ur10_robot.urdf", "ee_link", (0.025, 0.0, 0.0), X_OUT),
    # the hand's TCP sits between the fingers, whose tips reach 9 mm beyond it
    "panda": Robot("panda_description/urdf/panda.urdf", "panda_hand_tcp", (0.0, 0.0, 0.04), Z_OUT),
    "xarm7": Robot("xarm_description/urdf/xarm7.urdf", "link_eef", (0.0, 0.0, 0.025), Z_OUT),
    # Kinova Jaco 2 (6 DoF); its end-effector frame is at the fingertips, x out of the hand
    "kinova": Robot("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector", (0.03, 0.0, 0.0), X_OUT),
    # the gripper's jaws reach 15 cm beyond its stator along x
    "z1": Robot("z1_description/urdf/z1.urdf", "gripperStator", (0.18, 0.0, 0.0), X_OUT),
    # 5 arm joints: refused when the rig is built (a camera pose needs 6)
    "so101": Robot("so_arm_description/urdf/so101.urdf", "gripper_frame_link", (0.0, 0.0, 0.025), Z_OUT),
}
