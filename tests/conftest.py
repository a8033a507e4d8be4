"""Shared fixtures: the paper's cell and its arms' kinematics, built once per session."""

from __future__ import annotations

import pytest

from agrisim.cell import Cell, build_cell
from agrisim.config import CellConfig
from agrisim.kinematics import ArmKinematics


@pytest.fixture(scope="session")
def cell() -> Cell:
    return build_cell(CellConfig())


@pytest.fixture(scope="session")
def kin(cell: Cell) -> dict[str, ArmKinematics]:
    return {arm.name: ArmKinematics(arm) for arm in cell.arms}
