"""A third-party room, the way its author ships it: ``greenhouse`` of the test package
``tests/e2e/agrisim-greenhouse-room`` (trimesh's boxes on a gravel floor, daylight), installed as
a distribution into a temporary folder on ``sys.path``, found through the ``agrisim`` entry points
beside the built-in ``lab``, held to the room contract and chosen by ``[room] backend`` for a
run. The run's saved scene, read back by trimesh,, is the greenhouse's, with the plant in it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import installed
from PIL import Image

from agrisim.files import layout
from agrisim.registry import Registry, make_plugin_manager
from agrisim.testing.contracts import check

PACKAGE = Path(__file__).resolve().parent / "agrisim-greenhouse-room"


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The test package installed in a fresh folder on ``sys.path``; forgotten afterwards."""
    with installed(PACKAGE, tmp_path / "site", monkeypatch):
        yield tmp_path / "site"


def test_it_is_listed_and_keeps_the_room_contract(site: Path, cli) -> None:  # noqa: ANN001
    code, out, _ = cli(["plugins"])
    assert code == 0
    rooms = out[out.index("room:") : out.index("sink:")]
    assert "greenhouse" in rooms and "[agrisim-greenhouse-room 0.1.0]" in rooms and "lab" in rooms
    check("room", "greenhouse", Registry(make_plugin_manager()))
    code, out, err = cli(["run", "--set", "room.backend=attic", "--out", str(site / "never")])
    assert code == 2 and "'attic'" in err and "greenhouse, lab" in err and not (site / "never").exists()


def test_a_run_takes_place_in_it(site: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "run"
    args = ["run", "--physics", "kinematic", "--setpoints", "1x2", "--resolution", "96x54", "--recon", "none"]
    args += ["--set", "room.backend=greenhouse", "--set", "room.greenhouse.benches=2", "--shadow-samples", "0"]
    code, _, err = cli([*args, "--no-rrd", "--out", str(out)])
    assert code == 0, err
    saved = trimesh.load(out / layout.SCENE_GLB, force="scene")  # (named for the paper's lab, whatever the room)
    names = set(saved.geometry)
    assert {"gravel", "bench_0", "bench_1", "table", "pot", "plant"} <= names, names
    assert "bench_2" not in names and not any("cabinet" in n or "wall" in n for n in names), names
    # the plant stands in the pot: its lowest point below the pot's rim, above its bottom (glTF is y-up)
    placed = {g.metadata.get("name"): g for g in saved.dump(concatenate=False)}
    assert placed["pot"].bounds[0][1] < placed["plant"].bounds[0][1] < placed["pot"].bounds[1][1]
    labels = [np.asarray(Image.open(p)) for p in sorted((out / "labels").glob("*.png"))]
    assert len(labels) == 4 and all((lab > 0).any() for lab in labels)  # the plant seen in each view
