"""Configuration layering: defaults < TOML < flags, validated."""

from __future__ import annotations

import pytest

from agrisim.config import build_config, load_toml, merge
from agrisim.errors import ConfigError


def test_merge_is_pure_and_layers_tables():
    base = {"a": 1, "t": {"x": 1, "y": 2}}
    over = {"t": {"y": 3}, "b": 2}
    out = merge(base, over)
    assert out == {"a": 1, "b": 2, "t": {"x": 1, "y": 3}}
    assert base == {"a": 1, "t": {"x": 1, "y": 2}}  # inputs untouched


def test_defaults_reproduce_the_paper():
    cfg = build_config()
    assert cfg.routine.setpoints == "5x10" and cfg.routine.radius == 0.5
    assert cfg.cell.arm_distance == 1.0 and cfg.cell.stand_height == 0.95
    assert cfg.motion.reach_tolerance_mm == 0.05 and cfg.motion.reach_timeout == 5.0
    assert cfg.physics.backend == "pybullet" and cfg.planner.backend == "ompl"


def test_toml_then_flags(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text(
        'seed = 4\n[routine]\nsetpoints = "2x3"\n[physics]\nbackend = "kinematic"\n[physics.kinematic]\nrate = 480\n'
    )
    cfg = build_config(load_toml(f), {"routine": {"setpoints": "3x3"}})
    assert cfg.seed == 4 and cfg.routine.setpoints == "3x3"
    assert cfg.physics.backend == "kinematic" and cfg.physics.options_for("kinematic") == {"rate": 480}


@pytest.mark.parametrize(
    "layer, message",
    [
        ({"nope": 1}, "unknown setting 'nope'"),
        ({"routine": {"setpoints": "0x3"}}, "between 1 and 100"),
        ({"routine": {"setpoints": "five"}}, "LxC"),
        ({"motion": {"reach_tolerance_mm": 0}}, "motion.reach_tolerance_mm"),
        ({"seed": -1}, "seed"),
        ({"camera": {"resolution": "10x"}}, "WxH"),
    ],
)
def test_bad_values_name_the_setting(layer, message):
    with pytest.raises(ConfigError, match=message):
        build_config(layer)


def test_settings_that_moved_to_a_backend_land_in_its_table():
    """The familiar keys (and the flags that set them) are aliases of the backends' own options."""
    layer = {
        "plant": "helios:bean",
        "plant_age": 30,
        "render": {"shadow_samples": 0, "supersample": 2, "labels": "organs"},
        "output": {"no_rrd": True, "spawn": True},
    }
    cfg = build_config(layer)
    assert cfg.plants == {"helios:bean": {"age": 30}}
    assert cfg.renderer.options_for("raycast") == {"shadow_samples": 0, "supersample": 2}
    assert cfg.sink == {"rerun": {"save": False, "spawn": True}} and cfg.render.labels == "organs"
    assert layer["render"]["shadow_samples"] == 0, "the caller's layers are not changed"
    # the renderer chosen in any layer receives them; no renderer drops them
    assert build_config(layer, {"renderer": {"backend": "pybullet"}}).renderer.options_for("pybullet") == {
        "shadow_samples": 0,
        "supersample": 2,
    }
    assert build_config(layer, {"renderer": {"backend": "none"}}).renderer.model_extra == {}
    # the alias is the most specific: it wins over the table it names
    assert (
        build_config({"output": {"rrd": "a.rrd"}, "sink": {"rerun": {"path": "b.rrd"}}}).sink["rerun"]["path"]
        == "a.rrd"
    )


def test_backend_options_without_naming_the_backend_keep_the_default():
    cfg = build_config({"planner": {"ompl": {"algorithm": "PRM"}}})
    assert cfg.planner.backend == "ompl" and cfg.planner.options_for("ompl") == {"algorithm": "PRM"}


def test_malformed_toml(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text("seed = = 3\n")
    with pytest.raises(ConfigError, match="malformed TOML"):
        load_toml(f)
