"""Arms' URDFs made ready for a run, in memory: ``package://`` mesh paths absolute (pybullet
does not resolve them), a camera body and its OpenCV optical frame attached (:func:`camera_links`:
Pinocchio and every physics backend see one camera frame and collision box); the paper's UR10."""

from __future__ import annotations

import sysconfig
import xml.etree.ElementTree as ET
from functools import lru_cache
from importlib import metadata
from pathlib import Path

from agrisim.errors import UserError

ROBOT_DATA_DIST = "example-robot-data"
UR10_URDF = "example-robot-data/robots/ur_description/urdf/ur10_robot.urdf"
ARM_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
CAMERA_FRAME = "camera_optical_frame"
FLANGE_FRAME = "ee_link"

# The camera body: a 5 x 4 x 4 cm box whose +x is the optical axis, the optical centre on its
# front face (on the UR10, whose ee_link x points out of the flange: half a body in front of it).
CAMERA_BODY = (0.05, 0.04, 0.04)
_CAMERA_LINKS = """
  <joint name="camera_mount_joint" type="fixed">
    <parent link="{parent}"/>
    <child link="camera_link"/>
    <origin xyz="{xyz}" rpy="{rpy}"/>
  </joint>
  <link name="camera_link">
    <visual><geometry><box size="{size}"/></geometry></visual>
    <collision><geometry><box size="{size}"/></geometry></collision>
    <inertial><mass value="0.1"/><origin xyz="0 0 0"/>
      <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial>
  </link>
  <joint name="camera_optical_joint" type="fixed">
    <parent link="camera_link"/>
    <child link="camera_optical_frame"/>
    <!-- optical z = body x, optical x = -body y, optical y = -body z -->
    <origin xyz="{half:.6f} 0 0" rpy="-1.5707963267949 0 -1.5707963267949"/>
  </joint>
  <link name="camera_optical_frame"/>
""".replace("{size}", " ".join(map(str, CAMERA_BODY)))


def camera_links(parent: str, xyz: str, rpy: str) -> list[ET.Element]:
    """The camera body and :data:`CAMERA_FRAME` mounted on ``parent`` at ``xyz``, ``rpy`` (URDF text)."""
    text = _CAMERA_LINKS.format(parent=parent, xyz=xyz, rpy=rpy, half=CAMERA_BODY[0] / 2)
    return list(ET.fromstring(f"<r>{text}</r>"))


def give_massless_links_inertia(root: ET.Element) -> None:
    """A negligible inertia on every link without mass: pybullet would give each one 1 kg."""
    for link in root.iter("link"):
        inertial = link.find("inertial")
        mass = inertial.find("mass") if inertial is not None else None
        if mass is None or float(mass.get("value", "0")) <= 0.0:
            if inertial is not None:
                link.remove(inertial)
            link.append(ET.fromstring(TINY_INERTIAL))


@lru_cache(maxsize=1)
def robot_data_share() -> Path:
    """``<prefix>/share`` of the installed ``example-robot-data`` (it ships no Python module)."""
    candidates: list[Path] = []
    try:
        dist = metadata.distribution(ROBOT_DATA_DIST)
        for f in dist.files or ():
            if str(f).endswith("ur10_robot.urdf"):
                # an installed distribution (a PathDistribution) locates its files as Paths;
                # typeshed types the base class's locate_file, which returns a SimplePath
                full = Path(dist.locate_file(f)).resolve()  # type: ignore[arg-type]
                candidates.append(full.parents[4])  # .../share/example-robot-data/robots/ur_description/urdf
                break
    except metadata.PackageNotFoundError:
        pass
    candidates.append(Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share")
    for share in candidates:
        if (share / UR10_URDF).is_file():
            return share
    raise UserError(f"the UR10 URDF ({UR10_URDF}) was not found: install the '{ROBOT_DATA_DIST}' package")


def ur10_urdf_path() -> Path:
    return robot_data_share() / UR10_URDF


@lru_cache(maxsize=4)
def ur10_with_camera(urdf_path: str | None = None) -> str:
    """The UR10 URDF text: absolute mesh paths, small inertias, the camera on ``ee_link``."""
    path = Path(urdf_path) if urdf_path else ur10_urdf_path()
    if not path.is_file():
        raise UserError(f"URDF not found: {path}")
    share = robot_data_share()  # package:// URIs name example-robot-data's files
    try:
        root = ET.fromstring(path.read_text())
    except (ET.ParseError, OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read URDF {path}: {exc}") from None
    if root.tag != "robot":
        raise UserError(f"not a URDF robot description: {path}")
    root.extend(camera_links(FLANGE_FRAME, f"{CAMERA_BODY[0] / 2:.6f} 0 0", "0 0 0"))
    for mesh in root.iter("mesh"):
        filename = mesh.get("filename", "")
        if filename.startswith("package://"):
            mesh.set("filename", str(share / filename.removeprefix("package://")))
    give_massless_links_inertia(root)
    return ET.tostring(root, encoding="unicode")


TINY_INERTIAL = (
    '<inertial><mass value="0.001"/><origin xyz="0 0 0" rpy="0 0 0"/>'
    '<inertia ixx="1e-7" ixy="0" ixz="0" iyy="1e-7" iyz="0" izz="1e-7"/></inertial>'
)
