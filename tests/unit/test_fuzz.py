"""Hostile input, generated: configurations and flags broken in every way Hypothesis can combine
(wrong types, out of range, NaN and infinities, unknown keys and backends, missing or unusable
paths, broken assets) always give exit 2, one line naming the problem, no traceback and nothing
written."""

from __future__ import annotations

import math
import os
import uuid
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

#: a valid, cheap run: each example breaks it
BASE: dict[str, Any] = {
    "plant": "indian_cress",
    "renderer": {"backend": "none"},
    "physics": {"backend": "kinematic"},
    "routine": {"setpoints": "1x1"},
}


def _number(text: str) -> bool:
    """Would pydantic read ``text`` as a number? (it does, as float() and int() do: "0" is a
    fine stand height)"""
    try:
        float(text)
    except ValueError:
        return False
    return True


junk = st.one_of(
    st.text(max_size=12).filter(lambda t: not _number(t)),
    st.lists(st.integers(), max_size=3),
    st.dictionaries(st.text("abc", min_size=1, max_size=3), st.integers(), max_size=2),
    st.booleans(),
)
bad_float = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0, 1e12, -1e12]),
    junk,
)
#: floats with a fraction (1.0 is a fine integer seed; 1.5 is not), NaN and infinities
fractional = st.floats(allow_nan=True).filter(lambda x: not math.isfinite(x) or x != math.floor(x))
bad_int = st.one_of(st.sampled_from([-1, -(2**40), 2**40, 10**30]), fractional, junk)

#: (dotted key, strategy of values every one of which is invalid there)
FIELDS: list[tuple[str, st.SearchStrategy[Any]]] = [
    ("seed", bad_int),
    ("pcg_seed", bad_int),
    ("renderer.raycast.shadow_samples", st.one_of(st.sampled_from([-1, 33, 10**9]), junk)),
    ("renderer.raycast.supersample", st.one_of(st.sampled_from([0, 5, -3]), junk)),
    ("sink.rerun.spawn", st.one_of(st.sampled_from([2, "maybe", 1.5]), st.lists(st.integers(), max_size=2))),
    ("render.seg_mode", st.one_of(st.sampled_from(["Texture", "opacity", ""]), st.integers())),
    ("render.labels", st.one_of(st.sampled_from(["organ", "all"]), st.integers())),
    (
        "routine.setpoints",
        st.one_of(st.sampled_from(["0x1", "1x0", "x", "5x", "-1x2", "1000x1000", "5x10x2"]), st.integers()),
    ),
    ("routine.radius", bad_float),
    ("routine.csv", st.sampled_from(["/nonexistent/poses.csv", ""])),
    ("cell.arm_distance", bad_float),
    ("cell.stand_height", bad_float.filter(lambda x: x != 0.0)),  # (a stand of height 0 is the floor: allowed)
    ("camera.preset", st.one_of(st.sampled_from(["rpi4", "", "RPI3-WIDE-1080P"]), st.integers())),
    (
        "camera.resolution",
        st.one_of(st.sampled_from(["0x0", "axb", "1920", "-5x5", "100000x100000", "1920x1080x3"]), st.integers()),
    ),
    ("motion.max_acceleration", bad_float),
    ("motion.reach_timeout", bad_float),
    (
        "metrics.thresholds_mm",
        st.one_of(
            st.just([]),
            st.lists(bad_float, min_size=1, max_size=3).filter(
                lambda v: any(not isinstance(x, (int, float)) or not (0 < x <= 1000) or x != x for x in v)
            ),
        ),
    ),
    ("metrics.truth_samples", st.one_of(st.sampled_from([0, -5, 10**12]), junk)),
    ("physics.backend", st.text(min_size=1, max_size=10).filter(lambda s: s not in ("pybullet", "kinematic"))),
    ("planner.backend", st.text(min_size=1, max_size=10).filter(lambda s: s not in ("ompl", "direct"))),
    ("planner.ompl.time", bad_float),
    ("physics.pybullet.position_gain", bad_float),
    ("plant", st.sampled_from(["no_such_species", "/nonexistent/plant.glb", "plant.fbx", ""])),
]
UNKNOWN_SECTIONS = ["", "routine", "render", "cell", "camera", "motion", "output", "metrics", "physics", "planner"]


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return (
            '"'
            + v.replace("\\", "\\\\").replace('"', '\\"').encode("unicode_escape").decode().replace("\\\\u", "\\u")
            + '"'
        )
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f'"{k}" = {_toml_value(x)}' for k, x in v.items()) + "}"
    raise TypeError(v)


def _set(tree: dict[str, Any], dotted: str, value: Any) -> None:
    *parents, last = dotted.split(".")
    node = tree
    for key in parents:
        node = node.setdefault(key, {})
    node[last] = value


def _toml(tree: dict[str, Any]) -> str:
    """Dotted keys, one per line: valid TOML for any nesting."""
    lines: list[str] = []

    def walk(node: dict[str, Any], prefix: str) -> None:
        for key, value in node.items():
            name = f'{prefix}"{key}"'
            if isinstance(value, dict) and value and all(isinstance(k, str) for k in value) and key != "__leaf__":
                walk(value, name + ".")
            else:
                lines.append(f"{name} = {_toml_value(value)}")

    walk(tree, "")
    return "\n".join(lines) + "\n"


@st.composite
def broken_configs(draw: st.DrawFn) -> dict[str, Any]:
    tree: dict[str, Any] = {k: (dict(v) if isinstance(v, dict) else v) for k, v in BASE.items()}
    picks = draw(st.lists(st.sampled_from(range(len(FIELDS))), min_size=0, max_size=3, unique=True))
    for i in picks:
        key, values = FIELDS[i]
        _set(tree, key, draw(values))
    if not picks or draw(st.booleans()):
        section = draw(st.sampled_from(UNKNOWN_SECTIONS))
        name = draw(st.text("xyz_", min_size=1, max_size=8))
        _set(tree, f"{section}.{name}" if section else name, draw(st.integers()))
    return tree


def _tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture
def sandbox(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Path:
    root = tmp_path_factory.mktemp("fuzz")
    for var in list(os.environ):
        if var.startswith("AGRISIM_"):
            monkeypatch.delenv(var)
    monkeypatch.chdir(root)
    return root


def _expect_refusal(args: list[str], root: Path, cli) -> str:
    before = _tree(root)
    code, out, err = cli(args)
    assert code == 2, f"exit {code} for {args}: {err or out}"
    assert err.count("\n") == 1 and err.startswith("agrisim: error: "), err
    assert "Traceback" not in err
    after = [p for p in _tree(root) if not p.startswith("input")]
    assert after == [p for p in before if not p.startswith("input")], "something was written"
    return err


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)
@given(tree=broken_configs())
def test_broken_config_files_are_refused(tree: dict[str, Any], sandbox: Path, cli) -> None:
    path = sandbox / "input" / "config.toml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(_toml(tree))
    _expect_refusal(["run", "--config", str(path), "--out", str(sandbox / f"out-{uuid.uuid4().hex}")], sandbox, cli)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    key=st.sampled_from([k for k, _ in FIELDS]),
    text=st.one_of(st.sampled_from(["nan", "inf", "-1", "[", "{a=", "1e999", "''", "[1, 'x']"]), st.text(max_size=8)),
)
def test_broken_set_flags_are_refused(key: str, text: str, sandbox: Path, cli) -> None:
    """``--set KEY=VALUE`` with values parsed as TOML: whatever comes out is invalid for KEY,
    or the KEY itself is misspelt."""
    out = str(sandbox / f"out-{uuid.uuid4().hex}")
    base = ["run", "--renderer", "none", "--physics", "kinematic", "--setpoints", "1x1", "--out", out]
    from agrisim.config import build_config
    from agrisim.errors import UserError
    from agrisim.plugins.apps.flags import parse_value

    tree: dict[str, Any] = {}
    _set(tree, key, parse_value(text))
    try:  # a value that happens to be valid for KEY is not hostile: misspell the key instead
        build_config(BASE, tree)
        key = key + "_x"
    except UserError:
        pass
    _expect_refusal([*base, "--set", f"{key}={text}"], sandbox, cli)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    breakage=st.sampled_from(["nan", "inf", "face", "uv", "truncated", "huge", "empty", "binary", "degenerate"]),
    where=st.integers(0, 2),
)
def test_broken_assets_are_refused(breakage: str, where: int, sandbox: Path, cli) -> None:
    lines = ["v 0 0 0", "v 0.1 0 0", "v 0 0.1 0", "vt 0 0", "vt 1 0", "vt 0 1", "f 1/1 2/2 3/3"]
    if breakage in ("nan", "inf", "huge"):
        value = {"nan": "nan", "inf": "-inf", "huge": "1e300"}[breakage]
        lines[where] = f"v {value} 0 0" if where else f"v 0 {value} 0"
    elif breakage == "face":
        lines[-1] = f"f 1/1 2/2 {4 + where}/3"
    elif breakage == "uv":
        lines[-1] = f"f 1/1 2/{4 + where} 3/3"
    elif breakage == "truncated":
        lines = lines[:where] + ["v 0.1"]
    elif breakage == "empty":
        lines = lines[: 3 + where]  # no faces
    elif breakage == "degenerate":
        lines[1], lines[2] = "v 0 0 0", "v 0 0 0"
    path = sandbox / "input" / f"plant_{breakage}_{where}.obj"
    path.parent.mkdir(exist_ok=True)
    if breakage == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    else:
        path.write_text("\n".join(lines) + "\n")
    _expect_refusal(["run", "--plant", str(path), "--out", str(sandbox / f"out-{uuid.uuid4().hex}")], sandbox, cli)


def test_label_texture_of_only_background_is_refused(sandbox: Path, cli) -> None:
    import numpy as np
    from PIL import Image

    (sandbox / "input").mkdir()
    obj = sandbox / "input" / "card.obj"
    obj.write_text("v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    Image.fromarray(np.zeros((4, 6, 3), np.uint8)).save(sandbox / "input" / "labels.png")
    err = _expect_refusal(
        [
            "run",
            "--plant",
            str(obj),
            "--set",
            f"plant_file.label_texture={sandbox / 'input' / 'labels.png'}",
            "--out",
            "o",
        ],
        sandbox,
        cli,
    )
    assert "only background" in err


def test_output_under_a_regular_file_is_refused(sandbox: Path, cli) -> None:
    (sandbox / "input").mkdir()
    (sandbox / "input" / "afile").write_text("x")
    err = _expect_refusal(
        ["run", "--renderer", "none", "--out", str(sandbox / "input" / "afile" / "run")], sandbox, cli
    )
    assert "afile" in err
