"""A turntable camera as a one-joint robot, in the stage's frame.

The base sits on the stage's axis at its top. Its one joint, ``stage``, turns about ``-z``: at
angle ``a`` the stage (and the plant on it) has turned by ``a``, so in the plant's frame the
column and the camera have turned by ``-a`` about the axis. The column stands ``distance`` from
the axis on the floor; the camera body (the UR10's camera, :data:`agrisim.robot.urdf.CAMERA_BODY`)
is ``height`` above the stage's top, tilted down by ``tilt``, with its OpenCV optical frame
``camera_optical_frame`` on its front face. Only the first camera draws the column (the others
ride on it).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from agrisim.robot.urdf import CAMERA_BODY, camera_links, give_massless_links_inertia

#: the stage's joint, the one joint of every turntable camera
STAGE_JOINT = "stage"
#: the column's cross-section (along the radius, across it), m; it stands behind the cameras
COLUMN = (0.06, 0.08)
#: how far the column stands behind the camera bodies' backs, m (clear of collision checks' margins: the
#: arms that ride on it are other robots to them)
COLUMN_GAP = 0.05
#: the column's top above the highest camera, m
COLUMN_ABOVE = 0.1
#: the column's foot above the floor, m (standing on it, it would touch the floor's box)
COLUMN_LIFT = 0.03


def urdf_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw of a rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (pitch within
    +-90 degrees, as every camera here has)."""
    pitch = math.asin(-float(np.clip(R[2, 0], -1.0, 1.0)))
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def camera_body_pose(distance: float, height: float, tilt: float) -> np.ndarray:
    """The camera body's pose in the stage frame (before the stage turns): its centre on the
    +x side, its +x (the optical axis) towards the axis and down by ``tilt`` radians, its y
    horizontal."""
    forward = np.array([-math.cos(tilt), 0.0, -math.sin(tilt)])
    left = np.array([0.0, -1.0, 0.0])  # forward x left = up: a right-handed frame
    up = np.cross(forward, left)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([forward, left, up])
    # the optical centre (the body's front face) at (distance, 0, height)
    T[:3, 3] = np.array([distance, 0.0, height]) - forward * CAMERA_BODY[0] / 2
    return T


def camera_urdf(
    name: str, distance: float, height: float, tilt: float, *, column: tuple[float, float] | None, speed: float
) -> str:
    """The URDF of one turntable camera (see the module's docstring). ``column``: (its foot, its
    top) in z from the stage's top (the foot on the floor, below it), or None for a camera that
    rides on another's column; ``speed``: the stage's velocity limit, rad/s."""
    body = camera_body_pose(distance, height, tilt)
    column_parts = ""
    if column is not None:
        foot, top = column
        cx = distance + CAMERA_BODY[0] / 2 + COLUMN_GAP + COLUMN[0] / 2
        size = f"{COLUMN[0]:.6f} {COLUMN[1]:.6f} {top - foot:.6f}"
        where = f'<origin xyz="{cx:.6f} 0 {(top + foot) / 2:.6f}" rpy="0 0 0"/>'
        column_parts = (
            f'<visual>{where}<geometry><box size="{size}"/></geometry></visual>'
            f'<collision>{where}<geometry><box size="{size}"/></geometry></collision>'
        )
    root = ET.fromstring(
        f"""<robot name="{name}">
  <link name="base"/>
  <joint name="{STAGE_JOINT}" type="revolute">
    <parent link="base"/>
    <child link="column"/>
    <axis xyz="0 0 -1"/>
    <limit lower="{-2 * math.pi:.9f}" upper="{2 * math.pi:.9f}" velocity="{speed:.9f}" effort="100"/>
  </joint>
  <link name="column">{column_parts}</link>
</robot>"""
    )
    xyz = " ".join(f"{v:.9f}" for v in body[:3, 3])
    root.extend(camera_links("column", xyz, " ".join(f"{v:.12f}" for v in urdf_rpy(body[:3, :3]))))
    give_massless_links_inertia(root)
    return ET.tostring(root, encoding="unicode")
