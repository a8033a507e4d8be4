"""``agrisim/PlantView-v0``: Gymnasium's own checker accepts it; it is registered as Gymnasium
1.x expects without making ``import agrisim`` heavy; a seed gives the same episode; coverage
never falls and the reward is its gain less the motion's cost; a viewpoint the arm cannot reach
moves nothing; a leaf card is covered one side at a time; the episode's views are a run."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import LEAF_LABELS, leaf_card

from agrisim.files import layout
from agrisim.plugins.apps.nextview.env import PlantViewEnv

#: small and quick: kinematic arms, 160x90 views, a coarse map, few truth samples (the
#: reward's and the reconstruction's metrics': 20k, not 500k, each reset samples them)
SMALL = {
    "resolution": "160x90",
    "max_views": 3,
    "truth_samples": 20_000,
    "grid_cells": 16,
    "config": {
        "physics": {"backend": "kinematic"},
        "renderer": {"raycast": {"shadow_samples": 0}},
        "metrics": {"truth_samples": 20_000},
    },
}


def small_env(**kwargs: object) -> PlantViewEnv:
    return PlantViewEnv(**{"plant": "coltsfoot", **SMALL, **kwargs})  # type: ignore[arg-type]


def test_gymnasiums_checker_accepts_it() -> None:
    from gymnasium.utils.env_checker import check_env

    env = small_env()
    try:
        check_env(env, skip_render_check=True)
    finally:
        env.close()


def test_it_is_registered_on_import_and_by_module_qualified_id(tmp_path: Path) -> None:
    light = "import sys, agrisim; assert 'gymnasium' not in sys.modules, 'import agrisim loaded gymnasium'"
    subprocess.run([sys.executable, "-c", light], check=True)
    qualified = (
        "import gymnasium as gym; env = gym.make('agrisim.envs:agrisim/PlantView-v0', resolution='160x90'); "
        "print(type(env.unwrapped).__name__, env.action_space); env.close()"
    )
    done = subprocess.run([sys.executable, "-c", qualified], capture_output=True, text=True, check=True)
    assert "PlantViewEnv Discrete(100)" in done.stdout
    import agrisim.envs  # noqa: F401

    assert "agrisim/PlantView-v0" in gym.registry


EPISODE = """
import hashlib, json, sys
sys.path[:0] = sys.argv[1:3]
from test_plant_view_env import SMALL, small_env
env = small_env(config={**SMALL["config"], "recon": {"backend": "none"}})  # compared: what the agent sees
obs, _ = env.reset(seed=7)
steps = [env.step(a) for a in (0, 1, 52)]
env.close()
digest = lambda o: {k: hashlib.sha256(v.tobytes()).hexdigest() for k, v in o.items()}
print(json.dumps([digest(obs)] + [[digest(o), r, i["coverage"], i["motion_s"]] for o, r, *_, i in steps]))
"""


def test_a_seed_gives_the_same_episode() -> None:
    """Two episodes of one seed, each in a process of its own (as AsyncVectorEnv's workers and
    compare's Ray tasks are): the same observations, rewards, coverage and motion, bit for bit.
    Within one process a later episode may plan another path where OMPL is needed: OMPL's random
    generator is seeded once a process."""
    here = Path(__file__).resolve().parent
    runs = [
        json.loads(
            subprocess.run(
                [sys.executable, "-c", EPISODE, str(here), str(here.parent)], capture_output=True, text=True, check=True
            ).stdout
        )
        for _ in range(2)
    ]
    assert runs[0] == runs[1]
    assert runs[0][-1][2] > 0.3, "three views of coltsfoot see a good part of it"


def test_coverage_never_falls_and_the_reward_is_its_gain_less_the_motion(tmp_path: Path) -> None:
    env = small_env(max_views=6, out=tmp_path, motion_weight=0.02)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    coverage, done, info = 0.0, False, {}
    while not done:
        _, reward, terminated, truncated, info = env.step(int(rng.integers(env.action_space.n)))
        assert info["coverage"] >= coverage
        assert info["coverage_gain"] == pytest.approx(info["coverage"] - coverage, abs=1e-12)
        penalty = 0.0 if info["reached"] else 0.05
        assert reward == pytest.approx(info["coverage_gain"] - 0.02 * info["motion_s"] - penalty)
        coverage, done = info["coverage"], terminated or truncated
    env.close()
    # the episode is a run: its views on disk, its reconstruction measured
    run = Path(info["run_dir"])
    assert json.loads((run / layout.RUN_JSON).read_text())["status"] == "complete"
    assert len(list((run / "rgb").glob("*.png"))) == 6 - info["reach_failures"]
    assert info["metrics"]["labels"], "the reconstruction was measured"


def test_a_viewpoint_out_of_reach_moves_nothing() -> None:
    """r1 stands at x = +1 m: a view 0.8 m beyond the plant on the far side (x = -0.8) is 1.8 m
    from its base, past a UR10's 1.3 m."""
    env = small_env(actions="continuous")
    obs, _ = env.reset(seed=1)
    far = np.array([np.pi, np.pi / 3, 0.8, 0.0], np.float32)
    after, reward, _, _, info = env.step(far)
    assert not info["reached"] and info["reason"] and info["reach_failures"] == 1
    assert np.array_equal(after["joints"], obs["joints"])
    assert reward == pytest.approx(-0.05) and info["coverage"] == 0.0 and info["motion_s"] == 0.0
    with pytest.raises(AssertionError, match="invalid"):
        env.step(np.array([0.0, 0.0, 5.0, 0.0], np.float32))  # radius outside the space
    env.close()


def test_a_leaf_card_is_covered_one_side_at_a_time(tmp_path: Path) -> None:
    """A square card standing 60 degrees from flat, facing +x (r1's side): the view from r1's
    side sees its front, half the card's surface (its two sides); r2's, from -x, the back."""
    from agrisim.plugins.sinks.dataset.glb import export_glb

    card = leaf_card(0.1, np.full((8, 8), 255, np.uint8), 60.0, at=(0.0, 0.0, 0.1))
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # its normal from -y to +x
    export_glb(dataclasses.replace(card, vertices=card.vertices @ turn.T), tmp_path / "card.glb", LEAF_LABELS)
    env = small_env(plant=str(tmp_path / "card.glb"), actions="continuous", resolution="320x180", truth_samples=5_000)
    env.reset(seed=0)
    coverage = env.coverage
    _, _, _, _, front = env.step(np.array([0.0, np.pi / 4, 0.5, 0.0], np.float32))
    assert front["reached"]
    assert 0.45 < front["coverage"] <= 0.5 + 1e-9
    assert coverage.seen[:, 0].mean() > 0.9 and not coverage.seen[:, 1].any()
    _, _, _, _, back = env.step(np.array([np.pi, np.pi / 4, 0.5, 1.0], np.float32))
    assert back["reached"]
    assert back["coverage"] > 0.9 and coverage.seen[:, 1].mean() > 0.8
    env.close()


def test_it_runs_as_a_vector_of_processes_and_records_to_rerun(tmp_path: Path) -> None:
    """Two environments in their own processes (Gymnasium's AsyncVectorEnv), each episode
    recorded to Rerun in its run directory."""
    from gymnasium.vector import AsyncVectorEnv

    def make(k: int):  # noqa: ANN202
        return lambda: small_env(max_views=2, record=True, out=tmp_path / f"env{k}")

    envs = AsyncVectorEnv([make(0), make(1)])
    try:
        obs, _ = envs.reset(seed=[1, 2])
        assert obs["rgb"].shape == (2, 90, 160, 3)
        for actions in ([0, 1], [2, 3]):
            obs, rewards, terminated, truncated, infos = envs.step(np.array(actions))
        assert truncated.all() and (rewards > 0).all()
        assert (infos["coverage"] > 0).all()
    finally:
        envs.close()
    for k in range(2):
        run = tmp_path / f"env{k}" / "episode_0000"
        assert (run / layout.RECORDING).stat().st_size > 0
        assert len(list((run / "rgb").glob("*.png"))) == 2
