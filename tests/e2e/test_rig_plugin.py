"""A third-party rig, the way its author ships it: ``offset`` of the test package
``tests/e2e/agrisim-offset-rig`` (the paper's cell with its arms and stands moved sideways),
installed as a distribution into a temporary folder on ``sys.path``, found through the ``agrisim``
entry points beside the built-in ``paper``, held to the rig contract and chosen by ``--rig`` for a
run. The run puts the arms where the rig put them: their bases in the link poses, their stands in
the saved scene, and their cameras on the hemisphere turned to face the moved bases."""

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

PACKAGE = Path(__file__).resolve().parent / "agrisim-offset-rig"
SHIFT = 0.25
#: the paper's cell as [cell]'s defaults size it: arms 1 m either side on 0.95 m stands, table
#: top 0.8 m; the hemisphere's radius 0.5 m
ARM_X, STAND_TOP, TABLE_TOP, RADIUS = 1.0, 0.95, 0.8, 0.5


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The test package installed in a fresh folder on ``sys.path``; forgotten afterwards."""
    with installed(PACKAGE, tmp_path / "site", monkeypatch):
        yield tmp_path / "site"


def test_it_is_listed_and_keeps_the_rig_contract(site: Path, cli) -> None:  # noqa: ANN001
    code, out, _ = cli(["plugins"])
    assert code == 0
    rigs = out[out.index("rig:") : out.index("sink:")]
    assert "offset" in rigs and "[agrisim-offset-rig 0.1.0]" in rigs and "paper" in rigs
    check("rig", "offset", Registry(make_plugin_manager()))
    code, out, err = cli(["run", "--rig", "scara", "--out", str(site / "never")])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "'scara'" in err and "offset, paper" in err and not (site / "never").exists()


def test_a_rig_with_no_camera_is_refused_in_one_line(site: Path, cli) -> None:  # noqa: ANN001
    out = site / "never"
    code, _, err = cli(["run", "--rig", "offset", "--set", "rig.offset.arms=0", "--out", str(out)])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "rig 'offset'" in err and "no camera" in err and not out.exists()


def test_a_run_puts_the_arms_where_the_rig_put_them(site: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "run"
    args = ["run", "--rig", "offset", "--set", f"rig.offset.shift={SHIFT}", "--physics", "kinematic"]
    args += ["--setpoints", "1x2", "--resolution", "96x54", "--recon", "none", "--shadow-samples", "0"]
    code, _, err = cli([*args, "--no-rrd", "--out", str(out)])
    assert code == 0, err
    run = json.loads((out / layout.RUN_JSON).read_text())
    assert run["config"]["rig"] == {"backend": "offset", "offset": {"shift": SHIFT}}
    reached = {r["frame"] for r in run["results"] if r["reached"]}
    assert len(reached) >= 3 and {f[:2] for f in reached} == {"r1", "r2"}, run["results"]
    bases = {"r1": np.array([ARM_X, SHIFT, STAND_TOP]), "r2": np.array([-ARM_X, SHIFT, STAND_TOP])}
    cameras = json.loads((out / layout.CAMERAS_JSON).read_text())["frames"]
    assert set(cameras) == reached
    centre = np.array([0.0, 0.0, TABLE_TOP])
    for frame, shot in cameras.items():
        links = json.loads((out / layout.LINK_POSES / f"{frame}.json").read_text())
        for arm, base in bases.items():
            assert np.allclose(np.array(links[arm]["base_link"])[:3, 3], base, atol=1e-9), (frame, arm)
        # the paper's 1 x 2 hemisphere, its half turned to face the moved base: one level at
        # polar angle 36 degrees, columns at pi/19 and 18 pi/19 across the half
        base = bases[shot["robot"]]
        azimuth = np.arctan2(base[1], base[0]) - np.pi / 2 + np.pi / 19 * (1 + 17 * shot["setpoint"])
        polar = np.radians(36.0)
        eye = centre + RADIUS * np.array(
            [np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)]
        )
        assert np.allclose(np.array(shot["world_T_camera"])[:3, 3], eye, atol=1e-4), frame
    # the saved scene draws the stands where the rig put them (glTF is y-up: world y is -z)
    saved = trimesh.load(out / layout.SCENE_GLB, force="scene")
    placed = {g.metadata.get("name"): g for g in saved.dump(concatenate=False)}
    for arm, base in bases.items():
        centre_gltf = placed[f"{arm}_stand"].bounds.mean(axis=0)
        assert np.allclose(centre_gltf, [base[0], STAND_TOP / 2, -SHIFT], atol=1e-5), (arm, centre_gltf)


@pytest.mark.parametrize(
    "switch", [("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "1"), ("AGRISIM_LOAD_PLUGINS", "render-raycast")]
)
def test_a_finished_runs_readers_get_the_paper_rig_whatever_plugins_are_chosen(switch, monkeypatch) -> None:  # noqa: ANN001
    """The readers of a finished run (the bag exporter, traits) rebuild its cell from its saved
    config: the paper rig is agrisim's own, there as a run has it, whatever the switches that
    choose plugins say; its arms are the paper's two UR10s facing each other across the pot."""
    from agrisim.config import build_config
    from agrisim.validation import open_rig

    monkeypatch.setenv(*switch)
    _, cell = open_rig(build_config({}))
    assert cell.arm_names == ("r1", "r2")
    bases = [arm.world_T_base[:3, 3] for arm in cell.arms]
    np.testing.assert_allclose(bases[0][:2], -bases[1][:2], atol=1e-12)
    assert np.linalg.norm(bases[0][:2] - cell.plant_center[:2]) == pytest.approx(1.0)  # [cell] arm_distance
