"""Draw the robot cell, the paper's setpoints and the camera paths of a real run to
``docs/cell.png`` (matplotlib; the README's picture). Run: ``python bench/figure_cell.py``."""

from __future__ import annotations

import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from agrisim.config import build_config  # noqa: E402
from agrisim.episode import Episode  # noqa: E402
from agrisim.registry import hookimpl  # noqa: E402
from agrisim.robot.cell import Box, Cylinder  # noqa: E402

COLORS = {"r1": "#e07828", "r2": "#2882e6"}


class Paths:
    def __init__(self) -> None:
        self.camera: dict[str, list[np.ndarray]] = {}
        self.last_q: dict[str, np.ndarray] = {}

    @hookimpl
    def agrisim_trajectory(self, run, robot, trajectory):
        k = run.kinematics[robot]
        q = trajectory.executed.q[::6]
        self.camera.setdefault(robot, []).append(np.array([k.fk(x)[:3, 3] for x in q]))
        self.last_q[robot] = trajectory.executed.q[-1]


def collision_meshes(urdf: str) -> dict[str, trimesh.Trimesh]:
    out = {}
    for link in ET.fromstring(urdf).iter("link"):
        mesh = link.find("collision/geometry/mesh")
        if mesh is not None:
            out[link.get("name")] = trimesh.load(mesh.get("filename"), force="mesh")
    return out


def draw_box(ax, size, T, color, alpha) -> None:
    s = np.array(size) / 2
    corners = np.array([[x, y, z] for x in (-s[0], s[0]) for y in (-s[1], s[1]) for z in (-s[2], s[2])])
    c = corners @ T[:3, :3].T + T[:3, 3]
    faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    ax.add_collection3d(Poly3DCollection([c[f] for f in faces], facecolor=color, alpha=alpha, edgecolor="none"))


def draw_cylinder(ax, r, h, T, color, alpha) -> None:
    m = trimesh.creation.cylinder(radius=r, height=h, sections=32)
    m.apply_transform(T)
    ax.add_collection3d(Poly3DCollection(m.vertices[m.faces], facecolor=color, alpha=alpha, edgecolor="none"))


def main(out: Path) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        episode = Episode(
            build_config({"renderer": {"backend": "none"}, "output": {"out": f"{tmp}/run", "no_rrd": True}})
        )
        paths = Paths()
        episode.pm.register(paths)
        run, summary = episode.run()
    fig = plt.figure(figsize=(13, 6.2))
    for i, (elev, azim, title) in enumerate([(24, -62, "the cell"), (89, -90, "from above")]):
        ax = fig.add_subplot(1, 2, i + 1, projection="3d", computed_zorder=False)
        for ob in run.cell.obstacles:
            if ob.name == "floor":
                continue
            color = {"table": "#9a7048", "pot": "#aa5533", "plant_keepout": "#3c9a3c"}.get(ob.name, "#8c8c8c")
            alpha = 0.25 if ob.name == "plant_keepout" else 0.55
            if isinstance(ob, Box):
                draw_box(ax, ob.size, ob.world_T, color, alpha)
            elif isinstance(ob, Cylinder):
                draw_cylinder(ax, ob.radius, ob.height, ob.world_T, color, alpha)
        for arm in run.cell.arms:
            poses = run.kinematics[arm.name].link_poses(paths.last_q[arm.name])
            for name, mesh in collision_meshes(arm.urdf).items():
                v = mesh.vertices @ poses[name][:3, :3].T + poses[name][:3, 3]
                ax.add_collection3d(
                    Poly3DCollection(v[mesh.faces[::3]], facecolor=COLORS[arm.name], alpha=0.35, edgecolor="none")
                )
            for seg in paths.camera.get(arm.name, []):
                ax.plot(*seg.T, color=COLORS[arm.name], lw=0.8, alpha=0.8)
            sp = np.array([s.world_T_camera[:3, 3] for s in run.setpoints[arm.name]])
            reached = {r.frame for r in run.results if r.reached}
            ok = np.array([s.frame in reached for s in run.setpoints[arm.name]])
            ax.scatter(*sp[ok].T, s=10, color=COLORS[arm.name], depthshade=False, label=f"{arm.name} setpoints")
            if (~ok).any():
                ax.scatter(*sp[~ok].T, s=30, marker="x", color="k")
        ax.set_xlim(-1.3, 1.3)
        ax.set_ylim(-1.3, 1.3)
        ax.set_zlim(0, 2.0)
        ax.set_box_aspect((2.6, 2.6, 2.0))
        ax.view_init(elev=elev, azim=azim)
        ax.set_title(title)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        if i == 0:
            ax.legend(loc="upper left")
        else:
            ax.set_zticks([])
    fig.suptitle(
        f"agrisim run (pybullet + OMPL): {summary.reached}/{summary.setpoints} setpoints reached, "
        f"{summary.collisions} collisions; lines are the cameras' executed paths",
        fontsize=11,
    )
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/cell.png"))
