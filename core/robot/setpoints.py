"""Camera setpoints: a rig's default routine (:meth:`agrisim.interfaces.Rig.setpoints`), or poses
read from a CSV file."""

from __future__ import annotations

import csv
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agrisim.config import RoutineConfig
from agrisim.errors import UserError
from agrisim.robot.cell import Cell
from agrisim.scene.transforms import look_at, pose, rpy_matrix


@dataclass(frozen=True)
class Setpoint:
    """A camera target for one arm: ``world_T_camera`` (OpenCV optical frame)."""

    robot: str
    index: int  # per arm, 0-based: frame name r1_000 ...
    world_T_camera: np.ndarray

    @property
    def frame(self) -> str:
        return f"{self.robot}_{self.index:03d}"


#: a routine: each arm's setpoints in ``cell`` for the settings (a rig's ``setpoints``)
Routine = Callable[[Cell, RoutineConfig], dict[str, list[Setpoint]]]


def random_views(center: np.ndarray, rng: np.random.Generator, n: int = 50, radius: float = 0.5) -> list[np.ndarray]:
    """``n`` camera poses looking at ``center`` from ``radius`` m, drawn from ``rng``: polar
    angle 0.6-1.3 rad, azimuth within 1.2 rad of +x (the side an arm reaches). The IK timing's
    targets: ``bench/robot_episode.py`` and ``agrisim doctor`` time the same ones."""
    polar, azimuth = rng.uniform(0.6, 1.3, n), rng.uniform(-1.2, 1.2, n)
    return [
        look_at(center + radius * np.array([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)]), center)
        for p, a in zip(polar, azimuth, strict=True)
    ]


def from_csv(cell: Cell, path: Path) -> dict[str, list[Setpoint]]:
    """Camera poses from a CSV with columns x, y, z, roll, pitch, yaw (world frame, metres and
    radians, the optical frame's orientation as URDF rpy) and an optional ``robot`` column;
    rows without one go to the first arm."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as exc:
        raise UserError(f"cannot read setpoint CSV {path}: {exc}") from None
    need = ("x", "y", "z", "roll", "pitch", "yaw")
    if not rows or any(k not in rows[0] for k in need):
        raise UserError(f"setpoint CSV {path} needs a header with columns {', '.join(need)} (and optionally robot)")
    out: dict[str, list[Setpoint]] = {a.name: [] for a in cell.arms}
    for line, row in enumerate(rows, start=2):
        robot = (row.get("robot") or cell.arms[0].name).strip()
        if robot not in out:
            raise UserError(f"{path}:{line}: unknown robot {robot!r}; arms are {', '.join(out)}")
        try:
            x, y, z, roll, pitch, yaw = (float(row[k]) for k in need)
        except (TypeError, ValueError):
            raise UserError(f"{path}:{line}: x, y, z, roll, pitch, yaw must be numbers") from None
        if not np.all(np.isfinite([x, y, z, roll, pitch, yaw])):
            raise UserError(f"{path}:{line}: values must be finite")
        out[robot].append(Setpoint(robot, len(out[robot]), pose(rpy_matrix(roll, pitch, yaw), np.array([x, y, z]))))
    return out


def routine(cell: Cell, cfg: RoutineConfig, default: Routine) -> dict[str, list[Setpoint]]:
    """The configured routine's setpoints per arm: ``cfg.csv``'s, else ``default``'s (the rig's
    own, :meth:`agrisim.interfaces.Rig.setpoints`)."""
    return from_csv(cell, cfg.csv) if cfg.csv is not None else default(cell, cfg)
