"""``agrisim nextview``: each policy's episode on PlantView-v0, their coverage after every
view in nextview.json, a run directory per episode; the oracle (greedy on the truth) sees at
least as much as every other policy after every view; bad input exits 2 with one line and
writes nothing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_cli_errors import assert_one_line_error, snapshot

from agrisim.files import layout

#: 2x3 candidates an arm (12), kinematic arms, 160x90 views, no shadow rays, one planning
#: attempt: a move no path serves fails in 2 s, not 5 x 2 (the moves found take under 0.2 s);
#: each episode's reconstruction measured on 20k samples of the true surface, not 500k (the
#: coverage the policies are compared by is the environment's own samples)
QUICK = [
    "--resolution", "160x90",
    "--set", "physics.backend=kinematic",
    "--set", "routine.setpoints=2x3",
    "--set", "renderer.raycast.shadow_samples=0",
    "--set", "planner.ompl.attempts=1",
    "--set", "metrics.truth_samples=20000",
]  # fmt: skip


def test_policies_are_compared_and_the_oracle_leads(tmp_path: Path, cli) -> None:
    out = tmp_path / "nv"
    args = ["nextview", "--plant", "coltsfoot", "--policies", "random,oracle,volumetric,volumetric-motion,surface"]
    code, stdout, err = cli([*args, "--views", "5", "--out", str(out), *QUICK])
    assert code == 0, err
    doc = json.loads((out / "nextview.json").read_text())["plants"]["coltsfoot"]
    assert set(doc) == {"paper", "random", "oracle", "volumetric", "volumetric-motion", "surface"}
    assert len(doc["paper"]["coverage"]) == 12 and all(len(doc[p]["coverage"]) == 5 for p in doc if p != "paper")
    for name, episode in doc.items():
        coverage = episode["coverage"]
        assert all(b >= a for a, b in zip(coverage, coverage[1:], strict=False)), name
        assert all(b >= a for a, b in zip(episode["motion_s"], episode["motion_s"][1:], strict=False)), name
        run = Path(episode["run_dir"])
        assert json.loads((run / layout.RUN_JSON).read_text())["status"] == "complete"
        assert len(list((run / "rgb").glob("*.png"))) == len(coverage) - episode["reach_failures"]
    oracle = doc["oracle"]["coverage"]
    for name, episode in doc.items():
        for k, c in enumerate(episode["coverage"][:5]):
            assert oracle[k] >= c - 1e-9, f"{name} saw more than the oracle after {k + 1} views"
    assert (out / "nextview.png").stat().st_size > 0
    assert "| coltsfoot | oracle |" in stdout
    code, again, err = cli(["nextview", "--out", str(out), "--report"])
    assert code == 0 and again.strip() == stdout.strip().rsplit("\n", 1)[0].strip(), err
    code, _, err = cli([*args, "--views", "5", "--out", str(out), *QUICK])
    assert_one_line_error(code, err, ["nextview.json", "--overwrite"])


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--policies", "paper,clever"], ["unknown policy 'clever'", "volumetric"]),
        (["--plant", "nope"], ["unknown plant 'nope'"]),
        (["--views", "0"], ["--views", "0"]),
        (["--set", "cell.arm_distance=2.5"], ["none of the 12 candidate views", "reach"]),
    ],
    ids=["unknown-policy", "unknown-plant", "zero-views", "out-of-reach"],
)
def test_bad_input(tmp_path: Path, cli, args: list[str], expected: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    code, _, err = cli(["nextview", *QUICK, *args, "--out", str(tmp_path / "nv")])
    assert_one_line_error(code, err, expected)
    assert snapshot(tmp_path) == before, "something was written"
