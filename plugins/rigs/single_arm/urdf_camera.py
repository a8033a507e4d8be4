"""Any arm's URDF made ready for a run: mesh paths made absolute, the arm reduced to the joints
that move its camera, small inertias on massless links, and a camera body with its OpenCV
optical frame attached to a chosen link.

:func:`with_camera` generalises :func:`agrisim.robot.urdf.ur10_with_camera`: for the UR10 with
the camera on ``ee_link`` half a body in front of the flange it returns the same text, byte for
byte (the paper rig's images depend on it; ``tests/unit/test_single_arm.py`` checks it).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from agrisim.errors import UserError
from agrisim.robot.urdf import CAMERA_FRAME, camera_links, give_massless_links_inertia, robot_data_share

#: the link of the camera body (black in the renderers, see agrisim.plugins.render.arm_visuals)
CAMERA_LINK = "camera_link"
#: a joint's range when the URDF gives none (continuous joints): a whole turn either way, so
#: that IK's whole-turn shifts (ArmKinematics.nearest_equivalent) stay within it
FULL_TURNS = 2 * math.pi
#: joint velocity (rad/s) and effort (N m) where the URDF gives none: Ruckig needs a velocity
#: limit, and pybullet's motors take the effort as their force limit
DEFAULT_VELOCITY, DEFAULT_EFFORT = 1.0, 100.0


@dataclass(frozen=True)
class ArmDescription:
    """A URDF ready for :class:`agrisim.robot.cell.Arm`: its text and the joints that move the
    camera (from the root to the mount link, in tree order)."""

    urdf: str
    joints: tuple[str, ...]
    root: str
    mount: str


def _number(value: float) -> str:
    # "0" for zero and six decimals otherwise: the UR10's camera joint is written so
    return "0" if value == 0 else f"{value:.6f}"


def _resolve_mesh(filename: str, urdf_dir: Path | None, share: Path) -> str:
    """An absolute path for a mesh ``filename`` (pybullet and coal resolve no ``package://``):
    example-robot-data's share folder first, then the URDF's own folder and its parents."""
    if filename.startswith("file://"):
        return filename.removeprefix("file://")
    if filename.startswith("package://"):
        rest = filename.removeprefix("package://")
        candidates = [share / rest]
        if urdf_dir is not None:
            package, _, inner = rest.partition("/")
            for folder in (urdf_dir, *urdf_dir.parents):
                candidates += [folder / rest] + ([folder / inner] if folder.name == package else [])
        found = next((c for c in candidates if c.is_file()), candidates[0])
        return str(found)
    if urdf_dir is not None and not Path(filename).is_absolute():
        return str(urdf_dir / filename)
    return filename


def _chain(root: ET.Element, mount: str, path: Path) -> tuple[str, list[ET.Element]]:
    """The URDF's root link and the joints from it to ``mount``, root first."""
    joints = root.findall("joint")
    parent_of: dict[str, ET.Element] = {}
    for joint in joints:
        child, parent = joint.find("child"), joint.find("parent")
        if child is None or parent is None or not child.get("link") or not parent.get("link"):
            raise UserError(f"URDF {path}: joint {joint.get('name')!r} lacks a parent or child link")
        parent_of[child.get("link", "")] = joint
    links = [link.get("name", "") for link in root.findall("link")]
    if mount not in links:
        raise UserError(f"URDF {path} has no link {mount!r} to mount the camera on; its links: {', '.join(links)}")
    chain: list[ET.Element] = []
    link = mount
    while link in parent_of:
        joint = parent_of[link]
        chain.append(joint)
        link = joint.find("parent").get("link", "")  # type: ignore[union-attr]
        if len(chain) > len(joints):
            raise UserError(f"URDF {path}: its joints form a loop")
    return link, chain[::-1]


def _arm_joints(root: ET.Element, chain: list[ET.Element]) -> tuple[str, ...]:
    """Reduce the model to the joints on ``chain``: any other moving joint (a gripper's fingers)
    becomes fixed at zero, continuous joints become revolute over whole turns, and missing
    velocity and effort limits get defaults. Every backend then sees the same arm."""
    on_chain = {id(j) for j in chain}
    for joint in root.findall("joint"):
        kind = joint.get("type", "")
        if kind == "fixed":
            continue
        if id(joint) not in on_chain or kind not in ("revolute", "continuous", "prismatic"):
            joint.set("type", "fixed")
            for mimic in joint.findall("mimic"):
                joint.remove(mimic)
            continue
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit")
        if kind == "continuous":
            joint.set("type", "revolute")
            if float(limit.get("lower", "0")) >= float(limit.get("upper", "0")):
                limit.set("lower", repr(-FULL_TURNS))
                limit.set("upper", repr(FULL_TURNS))
        if float(limit.get("velocity", "0")) <= 0:
            limit.set("velocity", repr(DEFAULT_VELOCITY))
        if float(limit.get("effort", "0")) <= 0:
            limit.set("effort", repr(DEFAULT_EFFORT))
    return tuple(j.get("name", "") for j in chain if j.get("type") != "fixed")


def with_camera(
    path: Path,
    mount: str,
    xyz: tuple[float, float, float],
    rpy: tuple[float, float, float],
    *,
    relative_meshes: bool = True,
) -> ArmDescription:
    """The URDF at ``path`` with the camera body centred at ``xyz`` (m), turned by ``rpy``
    (rad; its +x axis the optical axis) in link ``mount``, ready for every backend.

    ``relative_meshes``: resolve mesh names without a scheme against the URDF's folder (a
    user's file); ``package://`` names are looked up in example-robot-data's share folder, then
    beside the URDF. Raises :class:`agrisim.errors.UserError` naming the file for a URDF that
    does not parse, a missing mount link, a mesh file that does not exist, or camera link
    names already taken.
    """
    if not path.is_file():
        raise UserError(f"URDF not found: {path}")
    try:
        root = ET.fromstring(path.read_text())
    except (ET.ParseError, OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read URDF {path}: {exc}") from None
    if root.tag != "robot":
        raise UserError(f"not a URDF robot description: {path}")
    names = {link.get("name", "") for link in root.findall("link")}
    taken = sorted(names & {CAMERA_LINK, CAMERA_FRAME})
    if taken:
        raise UserError(f"URDF {path} already has a link named {taken[0]!r}, which agrisim adds for its camera")
    for joint in root.findall("joint"):
        # Pinocchio names a frame after every link and joint: one name for both is ambiguous
        if joint.get("name") in names:
            joint.set("name", f"{joint.get('name')}_joint")
    base, chain = _chain(root, mount, path)
    joints = _arm_joints(root, chain)
    root.extend(camera_links(mount, " ".join(_number(v) for v in xyz), " ".join(_number(v) for v in rpy)))
    share = robot_data_share()
    urdf_dir = path.resolve().parent if relative_meshes else None
    for mesh in root.iter("mesh"):
        filename = _resolve_mesh(mesh.get("filename", ""), urdf_dir, share)
        if filename != mesh.get("filename", ""):
            mesh.set("filename", filename)
        if not Path(filename).is_file():
            raise UserError(f"URDF {path}: mesh file not found: {filename}")
    give_massless_links_inertia(root)
    return ArmDescription(ET.tostring(root, encoding="unicode"), joints, base, mount)
