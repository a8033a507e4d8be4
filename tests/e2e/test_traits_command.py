"""``agrisim traits``: a species' or a run's traits written to traits.json and printed; the
leaves are the ids the run's instance masks show; bad input exits 2 with one line and writes
nothing; finished work is not overwritten."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from test_cli_errors import assert_one_line_error, snapshot

from agrisim.plugins.apps.traits.opaque_area import face_opaque_area
from agrisim.plugins.plants.procedural import grow


def test_a_species_traits_are_written_and_not_overwritten(tmp_path: Path, cli) -> None:
    out = tmp_path / "traits.json"
    code, stdout, err = cli(["traits", "bog_marshcress", "--seed", "2", "--out", str(out)])
    assert code == 0, err
    doc = json.loads(out.read_text())
    mesh = grow("bog_marshcress", 2).mesh
    assert mesh.face_instance is not None
    opaque = face_opaque_area(mesh) > 0
    instances = set(np.unique(mesh.face_instance[opaque & (mesh.face_instance > 0)]).tolist())
    assert {leaf["id"] for leaf in doc["leaves"]} == instances
    plant = doc["plant"]
    assert (plant["name"], plant["seed"], plant["leaf_count"]) == ("bog_marshcress", 2, len(instances))
    assert plant["leaf_area_m2"] == pytest.approx(sum(leaf["area_m2"] for leaf in doc["leaves"]))
    assert f"{len(instances)} leaves" in stdout and str(out) in stdout
    assert doc["units"]["_m2"] == "square metres" and doc["definitions"] == "docs/traits.md"
    before = out.read_bytes()
    code, _, err = cli(["traits", "bog_marshcress", "--out", str(out)])
    assert_one_line_error(code, err, [str(out), "--overwrite"])
    assert out.read_bytes() == before
    code, _, err = cli(["traits", "bog_marshcress", "--seed", "3", "--out", str(out), "--overwrite"])
    assert code == 0, err
    assert json.loads(out.read_text())["plant"]["seed"] == 3


def test_a_runs_traits_go_into_it_and_name_the_leaves_its_masks_show(tmp_path: Path, cli, saved_runs) -> None:  # noqa: ANN001
    run = saved_runs.copy(tmp_path / "run", plant="coltsfoot", seed=4)
    code, _, err = cli(["traits", str(run)])
    assert code == 0, err
    doc = json.loads((run / "traits.json").read_text())
    assert doc["plant"]["seed"] == 4
    seen = set()
    for png in (run / "instances").glob("*.png"):
        seen |= set(np.unique(np.asarray(Image.open(png))).tolist()) - {0}
    assert seen, "the views show no leaf"
    assert seen <= {leaf["id"] for leaf in doc["leaves"]}


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["nope"], ["unknown plant 'nope'", "coltsfoot"]),
        (["{tmp}/afile.glb"], ["plant file", "afile.glb", "does not exist"]),
        (["{tmp}/points.ply"], ["no leaves", "face_instance"]),
        (["{tmp}/notarun"], ["notarun", "no run.json"]),
        (["coltsfoot", "--seed", "-1"], ["--seed", "-1"]),
        (["{tmp}/run", "--seed", "1"], ["--seed", "species"]),
        (["coltsfoot", "--measure"], ["--measure", "run's directory", "coltsfoot"]),
    ],
    ids=[
        "unknown-plant",
        "missing-file",
        "points-have-no-leaves",
        "not-a-run",
        "negative-seed",
        "seed-of-a-run",
        "measure-a-species",
    ],
)
def test_bad_input(tmp_path: Path, cli, args: list[str], expected: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
    (tmp_path / "points.ply").write_text(head + "end_header\n0 0 0\n0 0 0.1\n")
    (tmp_path / "notarun").mkdir()
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "run.json").write_text(json.dumps({"config": {"plant": "coltsfoot"}}))
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    code, stdout, err = cli(["traits", *(a.format(tmp=tmp_path) for a in args)])
    assert_one_line_error(code, err, expected)
    assert snapshot(tmp_path) == before, "something was written"


def test_plants_lists_each_species_leaf_count_and_area(cli) -> None:
    """``agrisim plants``: a species' leaves are its instances; its sampled leaf area is the
    exact one (agrisim traits) within the sampling's error (100,000 samples: 0.1% measured on
    coltsfoot; 2% allowed)."""
    from agrisim.plugins.apps.traits.truth import plant_traits

    code, stdout, err = cli(["plants"])
    assert code == 0, err
    header = stdout.splitlines()[0].split()
    assert "leaves" in header
    row = next(line.split() for line in stdout.splitlines() if line.startswith("coltsfoot "))
    exact = plant_traits(grow("coltsfoot", 0))
    assert int(row[3]) == exact.leaf_count
    assert float(row[4]) == pytest.approx(exact.leaf_area_m2 * 1e4, rel=0.02)
