"""The arms as ROS's TF tree: each URDF joint an edge from its parent link to its child link,
frames named ``<arm>/<link>`` under one ``world``. Shared by the ROS 2 bag export and the live
ROS session, so that a bag and a live session send the same tree.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # Pinocchio is imported by whoever builds the kinematics, not by this module
    from agrisim.robot.kinematics import ArmKinematics

#: the world frame every other frame hangs from
WORLD = "world"


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    kind: str  # revolute, fixed, ...
    parent: str
    child: str


def urdf_joints(urdf: str) -> list[UrdfJoint]:
    """The joints of a URDF document, as the TF tree's edges."""
    root = ET.fromstring(urdf)
    return [
        # a joint without <parent link=...> or <child link=...> is no URDF (never one of agrisim's)
        UrdfJoint(j.get("name", ""), j.get("type", ""), j.find("parent").get("link"), j.find("child").get("link"))  # type: ignore[union-attr, arg-type]
        for j in root.findall("joint")
    ]


def relative(world_T_parent: np.ndarray, world_T_child: np.ndarray) -> np.ndarray:
    """``parent_T_child`` of rigid transforms (batched over leading axes)."""
    R, p = world_T_parent[..., :3, :3], world_T_parent[..., :3, 3]
    out = np.zeros(np.broadcast_shapes(world_T_parent.shape, world_T_child.shape))
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt @ world_T_child[..., :3, :3]
    out[..., :3, 3] = (Rt @ (world_T_child[..., :3, 3] - p)[..., None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


class ArmFrames:
    """One arm's TF edges: the fixed ones once (``/tf_static``), the moving ones at any ``q``."""

    def __init__(self, arm: str, kinematics: ArmKinematics, urdf: str) -> None:
        self.arm, self.kin = arm, kinematics
        self.joints = urdf_joints(urdf)
        moving = [j for j in self.joints if j.kind != "fixed"]
        self._links = sorted({j.parent for j in moving} | {j.child for j in moving})
        self._parents = [self._links.index(j.parent) for j in moving]
        self._children = [self._links.index(j.child) for j in moving]
        self.moving_edges = [(f"{arm}/{j.parent}", f"{arm}/{j.child}") for j in moving]

    def moving(self, q: np.ndarray) -> np.ndarray:
        """``parent_T_child`` of every moving edge at ``q`` (J x 4 x 4)."""
        poses = self.kin.link_poses(q)
        world = np.stack([poses[name] for name in self._links])
        return relative(world[self._parents], world[self._children])

    def static(self, q: np.ndarray) -> tuple[list[tuple[str, str]], np.ndarray]:
        """``world`` -> the arm's URDF root, and every fixed joint (the same at any ``q``)."""
        poses = self.kin.link_poses(q)
        roots = {j.parent for j in self.joints} - {j.child for j in self.joints}
        edges, T = [], []
        for root in sorted(roots):
            edges.append((WORLD, f"{self.arm}/{root}"))
            T.append(poses[root])
        for j in self.joints:
            if j.kind == "fixed":
                edges.append((f"{self.arm}/{j.parent}", f"{self.arm}/{j.child}"))
                T.append(relative(poses[j.parent], poses[j.child]))
        return edges, np.asarray(T)


def quaternions(T: np.ndarray) -> np.ndarray:
    """(x, y, z, w) quaternions of the rotations of 4x4 transforms (batched), as ROS orders them."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(T[..., :3, :3].reshape(-1, 3, 3)).as_quat().reshape(*T.shape[:-2], 4)
