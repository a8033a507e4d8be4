"""Shared fixtures: the paper's cell and its arms' kinematics (built once per session), the CLI run
in-process (``cli``), and a plugin that keeps every rendered frame (``frames``). Tests marked
``gpu`` are skipped where Mitsuba finds no usable NVIDIA GPU (CI)."""

from __future__ import annotations

import pytest

from agrisim.config import CellConfig
from agrisim.interfaces import Frame
from agrisim.registry import hookimpl
from agrisim.robot.kinematics import ArmKinematics
from agrisim.scene.cell import Cell, build_cell


def _cuda_usable() -> bool:
    from agrisim.errors import ConfigError
    from agrisim.plugins.render.mitsuba.variant import resolve_variant

    try:  # (through agrisim, which points Dr.Jit at the right libLLVM before importing it)
        resolve_variant("cuda")
    except ConfigError:
        return False
    return True


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    gpu = [item for item in items if "gpu" in item.keywords]
    if gpu and not _cuda_usable():
        skip = pytest.mark.skip(reason="needs an NVIDIA GPU usable by Mitsuba (run on the GPU machine)")
        for item in gpu:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def cell() -> Cell:
    return build_cell(CellConfig())


@pytest.fixture(scope="session")
def kin(cell: Cell) -> dict[str, ArmKinematics]:
    return {arm.name: ArmKinematics(arm) for arm in cell.arms}


def small_run(out, **sections):  # noqa: ANN001, ANN201
    """Run a small complete episode into ``out`` and return it: kinematic arms, 1x3 setpoints
    (every one reached without an OMPL search), 320x180, raycast without shadow rays, no
    recording; ``sections`` (``plant="..."``, ``render={...}``, ``recon={...}``) go on top."""
    from agrisim.config import build_config, merge
    from agrisim.episode import Episode

    base = {
        "renderer": {"raycast": {"shadow_samples": 0}},
        "physics": {"backend": "kinematic"},
        "routine": {"setpoints": "1x3"},
        "camera": {"resolution": "320x180"},
        "output": {"out": str(out), "no_rrd": True},
    }
    _, summary = Episode(build_config(merge(base, sections))).run()
    assert summary.status == "complete"
    return out


def _run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Run ``agrisim ARGS`` in-process: (exit status, stdout, stderr)."""
    from agrisim.app.cli import main

    capsys.readouterr()
    try:
        code = main(args)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


class Frames:
    """A plugin object that keeps a copy of every capture's images, by frame name."""

    def __init__(self) -> None:
        self.images: dict[str, Frame] = {}

    @hookimpl
    def agrisim_capture(self, run, capture):  # noqa: ANN001 - pluggy passes what the hook names
        self.images[capture.frame] = capture.images.copy()


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]):  # noqa: ANN201 - returns the runner
    """``cli(args)`` runs ``agrisim ARGS`` in-process and returns (exit status, stdout, stderr)."""
    return lambda args: _run_cli(list(args), capsys)


@pytest.fixture
def frames() -> Frames:
    """A plugin object to register on an episode: it keeps a copy of every capture's images."""
    return Frames()
