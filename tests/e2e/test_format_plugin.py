"""Plant file formats behind the ``agrisim_plant_formats`` hook.

A third-party format, the way its author ships it: ``stl`` of the test package
``tests/e2e/agrisim-stl-format`` (STL through trimesh), installed as a distribution into a
temporary folder on ``sys.path``, found through the ``agrisim`` entry points beside agrisim's own
glTF, OBJ and point-cloud readers, held to the format contract, and used by a run whose plant is
an STL file: the run's saved plant, read back by trimesh, is the file's surface, placed.

And a plain mesh file without agrisim's extras (an OBJ two leaf cards, as trimesh writes it) gets
its leaf instances from its connected pieces, so that ``agrisim traits`` measures it leaf by leaf.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import installed

from agrisim.files import layout
from agrisim.registry import Registry, make_plugin_manager
from agrisim.testing.contracts import check

PACKAGE = Path(__file__).resolve().parent / "agrisim-stl-format"


def two_cards() -> trimesh.Trimesh:
    """Two 10 x 4 cm leaf cards 5 cm apart, tilted 30 degrees (z up, metres)."""
    cards = []
    for x in (-0.08, 0.03):
        card = trimesh.creation.box((0.10, 0.04, 1e-9))
        card = trimesh.Trimesh(card.vertices, card.faces[card.face_normals[:, 2] > 0.5])  # the top face only
        card.apply_transform(trimesh.transformations.rotation_matrix(np.radians(30), (1, 0, 0)))
        card.apply_translation((x + 0.05, 0.0, 0.10))
        cards.append(card)
    return trimesh.util.concatenate(cards)


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The test package installed in a fresh folder on ``sys.path``; forgotten afterwards."""
    with installed(PACKAGE, tmp_path / "site", monkeypatch):
        yield tmp_path / "site"


def test_it_is_listed_keeps_the_format_contract_and_a_run_reads_it(site: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    code, out, _ = cli(["plugins"])
    assert code == 0
    formats = out[out.index("format:") : out.index("room:")]
    assert "stl" in formats and "[agrisim-stl-format 0.1.0]" in formats and "gltf" in formats
    check("format", "stl", Registry(make_plugin_manager()))
    code, _, err = cli(["run", "--plant", str(tmp_path / "absent.ply"), "--out", str(tmp_path / "never")])
    assert code == 2 and not (tmp_path / "never").exists()
    code, _, err = cli(["run", "--plant", "no_such_species", "--out", str(tmp_path / "never")])
    assert code == 2 and "a .stl/.glb/.gltf/.obj mesh or .ply/.pcd point cloud" in err  # (third parties asked first)

    scan = tmp_path / "scan.stl"
    cards = two_cards()
    cards.export(scan)
    out = tmp_path / "run"
    args = ["run", "--plant", str(scan), "--physics", "kinematic", "--setpoints", "1x1", "--resolution", "96x54"]
    code, _, err = cli([*args, "--recon", "none", "--shadow-samples", "0", "--no-rrd", "--out", str(out)])
    assert code == 0, err
    saved = trimesh.load(out / layout.PLANT_GLB, force="mesh")
    assert saved.area == pytest.approx(cards.area, rel=1e-5)  # the file's surface, whole
    # placed in the cell: its lowest point on the soil, centred over the pot (glTF is y-up)
    lo, hi = saved.bounds
    assert abs((lo[0] + hi[0]) / 2) < 1e-6 and abs((lo[2] + hi[2]) / 2) < 1e-6


def test_a_plain_obj_gets_a_leaf_per_piece_and_its_traits(tmp_path: Path, cli) -> None:  # noqa: ANN001
    card = tmp_path / "cards.obj"
    cards = two_cards()
    # OBJ has no up axis and is read y-up, as most exporters write it: (x, y, z) -> (x, z, -y)
    cards.apply_transform(np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]]))
    cards.export(card)
    out = tmp_path / "traits.json"
    code, _, err = cli(["traits", str(card), "--out", str(out)])
    assert code == 0, err
    doc = json.loads(out.read_text())
    leaves = doc["leaves"]
    assert len(leaves) == 2
    for leaf in leaves:  # each card's area, its inclination from the horizontal
        assert leaf["area_m2"] == pytest.approx(0.004, rel=1e-5)
        assert leaf["inclination_deg"] == pytest.approx(30.0, abs=0.5)
