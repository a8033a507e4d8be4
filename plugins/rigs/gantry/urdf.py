"""The gantry as one robot: a Cartesian XYZ stage and a pan-tilt head, in URDF primitives.

The base sits on the floor below the plant (world axes). Joints, in order:

* ``x`` (prismatic along x): the ``bridge``, a beam across the portal's two rails, riding
  :data:`RIDE_GAP` above their tops;
* ``y`` (prismatic along y): the ``carriage`` running along the bridge on its -x face;
* ``z`` (prismatic along z): the ``ram``, a vertical rod sliding through the carriage, the pan
  motor at its lower end; the joint's value is the height of the optical centre above the floor;
* ``pan`` (revolute about z, the ram's axis): the ``head``, a yoke under the motor;
* ``tilt`` (revolute about the yoke's y axis, positive looking down): the ``cradle`` with the
  camera body (:func:`agrisim.robot.urdf.camera_links`), whose +x is the optical axis.

Both head axes pass through the optical centre (the camera body's front face), so the camera's
position is the stage's (x, y, z) whatever the head does, and its body turns by Rz(pan) Ry(tilt):
at zero pan and tilt it looks along +x, level. Its image's x axis is then horizontal, as
:func:`agrisim.scene.transforms.look_at` makes it, so every look-at viewpoint has one solution
(:func:`viewpoint_joints`). The fixed portal (posts and rails) is not part of the robot: it is
the cell's obstacles (:func:`portal`), drawn by the room and checked for collisions.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from agrisim.robot.cell import Box
from agrisim.robot.urdf import CAMERA_BODY, camera_links, give_massless_links_inertia
from agrisim.scene.transforms import translation

__all__ = [
    "HEAD_TOP",
    "JOINTS",
    "PAN_LIMIT",
    "TILT_LIMIT",
    "gantry_urdf",
    "portal",
    "portal_posts",
    "viewpoint_joints",
    "z_max",
]

#: the gantry's joints, from the base to the camera
JOINTS = ("x", "y", "z", "pan", "tilt")
#: the pan joint's range either way, rad: half a turn covers every azimuth
PAN_LIMIT = math.pi
#: the tilt joint's range either way, rad: a little past straight down (+90 degrees)
TILT_LIMIT = math.radians(100.0)

#: the rails' cross-section (width along y, height), m; their tops are ``beam_height``
RAIL = (0.08, 0.10)
#: the posts' side, m; they carry the rails at the portal's four corners
POST = 0.08
#: the portal's posts stand this far beyond the stage's travel in x, and in y, m: the bridge
#: (behind the ram, :data:`BRIDGE_OFFSET`) stays on the rails, the head clear of them
PORTAL_MARGIN = (0.2, 0.15)
#: the bridge's cross-section (depth along x, height), m
BRIDGE = (0.08, 0.10)
#: the bridge's centre is this far from the ram's axis along +x, m (the carriage between them)
BRIDGE_OFFSET = 0.09
#: how far the bridge and the carriage ride above the rails' tops, m: clear of them by more than
#: a physics backend's clearance, so riding is not a collision
RIDE_GAP = 0.02
#: the carriage's extent along x from the ram's axis (its back, the bridge's face), m; its width
#: along y
CARRIAGE_X = (-0.04, BRIDGE_OFFSET - BRIDGE[0] / 2)
CARRIAGE_Y = 0.12
#: the ram's radius, m
RAM_RADIUS = 0.02
#: how far the ram's top stands above the carriage at the ram's lowest, m
RAM_ABOVE = 0.05
#: the pan motor under the ram: radius, bottom and top above the optical centre, m
MOTOR = (0.045, 0.085, 0.14)
#: the top of the head (the pan motor) above the optical centre, m: the camera reaches up to this
#: much below the rails' tops, the head then 2 cm (:data:`RIDE_GAP`) under the carriage
HEAD_TOP = MOTOR[2]
#: the yoke's plate under the motor (bottom, top above the optical centre) and its arms (distance
#: from the tilt axis's middle, their lowest point), m. The camera body turns about its front
#: face within sqrt(0.05^2 + 0.02^2) = 0.054 m of it, so the plate (0.07) clears it at any tilt;
#: the arms stand beside it (0.02 m half width) and end above the lens's plane, out of its view.
YOKE_PLATE = (0.07, 0.085)
YOKE_ARMS = (0.04, -0.012)

#: (material name, RGBA) of the moving parts: anodised aluminium beams, dark motors and yoke
_METAL = ("gantry_metal", "0.72 0.73 0.75 1")
_DARK = ("gantry_dark", "0.12 0.12 0.13 1")


def z_max(beam_height: float) -> float:
    """The highest the optical centre goes under rails ``beam_height`` m high, m (rounded as the
    URDF writes the limit, so that a home there is within it)."""
    return round(beam_height - HEAD_TOP, 9)


def _geometry(shape: str, xyz: tuple[float, float, float], material: tuple[str, str]) -> str:
    """A visual and its collision, the same primitive at ``xyz`` (m) in the link."""
    where = f'<origin xyz="{xyz[0]:.6f} {xyz[1]:.6f} {xyz[2]:.6f}" rpy="0 0 0"/>'
    name, rgba = material
    return (
        f'<visual>{where}<geometry>{shape}</geometry><material name="{name}"><color rgba="{rgba}"/></material></visual>'
        f"<collision>{where}<geometry>{shape}</geometry></collision>"
    )


def _box(size: tuple[float, float, float]) -> str:
    return f'<box size="{size[0]:.6f} {size[1]:.6f} {size[2]:.6f}"/>'


def _cylinder(radius: float, length: float) -> str:
    return f'<cylinder radius="{radius:.6f}" length="{length:.6f}"/>'


def _joint(name: str, kind: str, parent: str, child: str, axis: str, limits: tuple[float, float], speed: float) -> str:
    lo, hi = limits
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="{axis}"/>'
        f'<limit lower="{lo:.9f}" upper="{hi:.9f}" velocity="{speed:.9f}" effort="200"/></joint>'
    )


def gantry_urdf(
    name: str,
    *,
    travel: tuple[float, float],
    beam_height: float,
    z_min: float,
    speeds: tuple[float, float, float],
    head_speed: float,
) -> str:
    """The gantry's URDF (see the module's docstring). ``travel``: the stage's travel in x and y,
    m, centred on the base; ``beam_height``: the rails' tops above the base, m; ``z_min``: the
    optical centre's lowest height, m; ``speeds``: the x, y and z axes' limits, m/s;
    ``head_speed``: pan's and tilt's, rad/s."""
    tx, ty = travel
    py = ty / 2 + PORTAL_MARGIN[1]
    ride = beam_height + RIDE_GAP + BRIDGE[1] / 2  # the bridge's and the carriage's centre height
    bridge = _geometry(_box((BRIDGE[0], 2 * py + RAIL[0], BRIDGE[1])), (BRIDGE_OFFSET, 0.0, ride), _METAL)
    depth = CARRIAGE_X[1] - CARRIAGE_X[0]
    carriage = _geometry(_box((depth, CARRIAGE_Y, BRIDGE[1])), ((CARRIAGE_X[0] + CARRIAGE_X[1]) / 2, 0.0, ride), _DARK)
    # at its lowest the ram still passes through the carriage and RAM_ABOVE beyond it
    length = beam_height + RIDE_GAP + BRIDGE[1] + RAM_ABOVE - z_min - HEAD_TOP
    ram = _geometry(_cylinder(RAM_RADIUS, length), (0.0, 0.0, HEAD_TOP + length / 2), _METAL)
    motor = _geometry(_cylinder(MOTOR[0], MOTOR[2] - MOTOR[1]), (0.0, 0.0, (MOTOR[1] + MOTOR[2]) / 2), _DARK)
    plate = YOKE_PLATE[1] - YOKE_PLATE[0]
    yoke = _geometry(
        _box((0.04, 2 * YOKE_ARMS[0] + 0.02, plate)), (0.0, 0.0, (YOKE_PLATE[0] + YOKE_PLATE[1]) / 2), _DARK
    )
    arm_length = YOKE_PLATE[0] - YOKE_ARMS[1]
    for side in (1.0, -1.0):
        centre = (0.0, side * YOKE_ARMS[0], YOKE_ARMS[1] + arm_length / 2)
        yoke += _geometry(_box((0.03, 0.01, arm_length)), centre, _DARK)
    pan, tilt = (-PAN_LIMIT, PAN_LIMIT), (-TILT_LIMIT, TILT_LIMIT)
    vx, vy, vz = speeds
    root = ET.fromstring(
        f"""<robot name="{name}">
  <link name="base"/>
  {_joint("x", "prismatic", "base", "bridge", "1 0 0", (-tx / 2, tx / 2), vx)}
  <link name="bridge">{bridge}</link>
  {_joint("y", "prismatic", "bridge", "carriage", "0 1 0", (-ty / 2, ty / 2), vy)}
  <link name="carriage">{carriage}</link>
  {_joint("z", "prismatic", "carriage", "ram", "0 0 1", (z_min, z_max(beam_height)), vz)}
  <link name="ram">{ram}{motor}</link>
  {_joint("pan", "revolute", "ram", "head", "0 0 1", pan, head_speed)}
  <link name="head">{yoke}</link>
  {_joint("tilt", "revolute", "head", "cradle", "0 1 0", tilt, head_speed)}
  <link name="cradle"/>
</robot>"""
    )
    # the body behind its front face, which is the optical centre, on both head axes
    root.extend(camera_links("cradle", f"{-CAMERA_BODY[0] / 2:.6f} 0 0", "0 0 0"))
    give_massless_links_inertia(root)
    return ET.tostring(root, encoding="unicode")


def portal_posts(travel: tuple[float, float]) -> tuple[float, float]:
    """Where the portal's posts stand, (x, y) from the plant's axis, m (one at each sign)."""
    return travel[0] / 2 + PORTAL_MARGIN[0], travel[1] / 2 + PORTAL_MARGIN[1]


def portal(travel: tuple[float, float], beam_height: float, centre: np.ndarray) -> list[Box]:
    """The fixed portal around the plant's axis through ``centre`` (x, y): four posts under two
    rails along x, whose tops are ``beam_height`` m above the floor. ``portal_post_1`` (+x, -y)
    comes first: the robot's stand."""
    px, py = portal_posts(travel)
    post_height = beam_height - RAIL[1]
    cx, cy = float(centre[0]), float(centre[1])
    boxes = [
        Box(f"portal_post_{i + 1}", (POST, POST, post_height), translation(cx + sx * px, cy + sy * py, post_height / 2))
        for i, (sx, sy) in enumerate(((1, -1), (1, 1), (-1, 1), (-1, -1)))
    ]
    rail = (2 * px + POST, RAIL[0], RAIL[1])
    boxes += [
        Box(f"portal_rail_{i + 1}", rail, translation(cx, cy + sy * py, beam_height - RAIL[1] / 2))
        for i, sy in enumerate((-1, 1))
    ]
    return boxes


def viewpoint_joints(world_T_camera: np.ndarray, world_T_base: np.ndarray) -> np.ndarray:
    """The joints (x, y, z, pan, tilt) that put the optical frame at ``world_T_camera``, in closed
    form: the position is the stage's, the image's x axis ``(sin pan, -cos pan, 0)`` in the base
    frame gives pan, and the optical axis's drop below level gives tilt. Exact for a pose whose
    image x axis is level (every :func:`agrisim.scene.transforms.look_at` pose); pan within
    (-pi, pi], tilt within [-pi/2, pi/2]. Raises ValueError for a rolled image, which the head
    cannot make."""
    base_T = np.linalg.inv(np.asarray(world_T_base, float))
    T = base_T @ np.asarray(world_T_camera, float)
    right, forward = T[:3, 0], T[:3, 2]
    if abs(right[2]) > 1e-9:
        raise ValueError(f"the camera's image is rolled by {math.degrees(math.asin(right[2])):.3g} degrees")
    pan = math.atan2(right[0], -right[1])
    level = forward[0] * math.cos(pan) + forward[1] * math.sin(pan)
    tilt = math.atan2(-forward[2], level)
    return np.array([T[0, 3], T[1, 3], T[2, 3], pan, tilt])
