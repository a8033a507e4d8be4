"""Plugin discovery, the way users meet it: real distributions found by ``importlib.metadata``.

Each test builds throwaway distributions in a temp folder (a ``<name>.dist-info`` with METADATA
and entry_points.txt next to the module) and puts the folder on ``sys.path``; nothing is
registered by hand. The example package in ``examples/agrisim-example-planner`` is installed this
way from its own ``pyproject.toml`` and module, so the example is what gets tested.
"""

from __future__ import annotations

import inspect
import json
import os
import pkgutil
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import isolated_env

import agrisim
from agrisim import hookspecs
from agrisim.app.cli import main
from agrisim.config import CellConfig, MotionConfig, build_config
from agrisim.errors import BackendFailure, PluginError, UserError
from agrisim.interfaces import PlanningFailed, PlantSpecies, Reconstructor, Renderer
from agrisim.plugins.physics.kinematic import KinematicOptions
from agrisim.plugins.physics.kinematic.backend import KinematicPhysics
from agrisim.plugins.planners.direct import DirectPlanner
from agrisim.plugins.rigs.paper.cell import build_cell
from agrisim.registry import PROVIDER_HOOKS, NoOptions, Registry, make_plugin_manager
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.segments import path_is_valid, segment_samples

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "agrisim-example-planner"
EXAMPLE_MODULE = "agrisim_example_planner"


# ------------------------------------------------------------------------- helpers


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """A fresh folder on ``sys.path`` for throwaway distributions; the modules imported from it
    are forgotten afterwards so that the next test imports its own."""
    root = tmp_path / "site"
    root.mkdir()
    monkeypatch.syspath_prepend(str(root))
    for var in ("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "AGRISIM_LOAD_PLUGINS", "AGRISIM_TRACE_PLUGINS"):
        monkeypatch.delenv(var, raising=False)
    before = set(sys.modules)
    yield root
    for name in set(sys.modules) - before:
        module = sys.modules.get(name)
        if str(getattr(module, "__file__", "") or "").startswith(str(root)):
            del sys.modules[name]


def make_dist(
    site: Path,
    name: str,
    modules: dict[str, str],
    entry_points: dict[str, str],
    version: str = "0.1.0",
) -> Path:
    """Write distribution ``name``: its modules and a dist-info declaring ``entry_points``
    (entry-point name -> module) in the ``agrisim`` group, as pip would install it."""
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    lines = "".join(f"{ep} = {module}\n" for ep, module in entry_points.items())
    (info / "entry_points.txt").write_text(f"[agrisim]\n{lines}")
    for module, source in modules.items():
        (site / f"{module}.py").write_text(textwrap.dedent(source))
    return info


def install_example(site: Path) -> tuple[str, str]:
    """The example package as pip would lay it out, from its own pyproject.toml and module.
    Returns (distribution name, version)."""
    project = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())["project"]
    modules = {EXAMPLE_MODULE: (EXAMPLE / f"{EXAMPLE_MODULE}.py").read_text()}
    make_dist(site, project["name"], modules, project["entry-points"]["agrisim"], project["version"])
    return project["name"], project["version"]


def planner_source(backend: str, base: str = "direct") -> str:
    """A module whose ``agrisim_planners`` provides ``backend`` (a copy of a built-in planner)."""
    return f"""
        from agrisim import BackendSpec, hookimpl
        from agrisim.plugins.planners.direct import DirectPlanner

        @hookimpl
        def agrisim_planners():
            return [BackendSpec(name={backend!r}, factory=DirectPlanner, description="test planner")]
    """


def listed(text: str, kind: str) -> dict[str, str]:
    """``agrisim plugins`` output -> {backend name: its line} for one kind."""
    out: dict[str, str] = {}
    section = None
    for line in text.splitlines():
        if not line.startswith(" "):
            section = line.rstrip(":")
        elif section == kind and line.strip() and not line.strip().startswith(("limits:", "can:", "(none")):
            out[line.split()[0]] = line
    return out


def plugins_cli(capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    capsys.readouterr()
    try:
        code = main(["plugins"])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def subprocess_env(site: Path, **extra: str) -> dict[str, str]:
    env = isolated_env()
    env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env.update(extra)
    return env


# ------------------------------------------------------------ a third-party distribution


def test_example_package_is_discovered_with_its_distribution(site: Path, capsys) -> None:
    dist, version = install_example(site)
    assert dist == "agrisim-example-planner"

    code, out, err = plugins_cli(capsys)
    assert code == 0, err
    planners = listed(out, "planner")
    assert {"direct", "ompl", "waypoint"} <= set(planners)
    assert f"[{dist} {version}]" in planners["waypoint"]
    assert "[agrisim " in planners["direct"]  # built-ins come through the same path

    spec = Registry(make_plugin_manager()).get("planner", "waypoint")
    assert spec.distribution == f"{dist} {version}"
    assert spec.options_model.model_json_schema()["additionalProperties"] is False
    for name, fld in spec.options_model.model_fields.items():
        assert fld.description, f"option {name!r} has no docstring"


def test_example_package_is_discovered_in_a_fresh_interpreter(site: Path) -> None:
    dist, version = install_example(site)
    proc = subprocess.run(
        [sys.executable, "-m", "agrisim", "plugins"],
        capture_output=True,
        text=True,
        env=subprocess_env(site),
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert f"[{dist} {version}]" in listed(proc.stdout, "planner")["waypoint"]


def test_run_with_the_example_planner(site: Path, tmp_path: Path, capsys) -> None:
    """End to end with the plugin's planner, chosen by name on the command line."""
    install_example(site)
    out = tmp_path / "run"
    args = [
        "run",
        "--physics",
        "kinematic",
        "--planner",
        "waypoint",
        "--setpoints",
        "1x2",
        "--no-rrd",
        "--renderer",
        "none",
    ]
    assert main([*args, "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    run = json.loads((out / "run.json").read_text())
    assert run["backends"]["planner"] == "waypoint"
    assert run["backend_options"]["planner"]["retract"] == pytest.approx(1.0)
    assert run["status"] == "complete"
    assert run["summary"]["setpoints"] == 4
    assert run["summary"]["reached"] == 4, [r["reason"] for r in run["results"] if not r["reached"]]
    assert all(r["ee_error_mm"] <= 0.05 for r in run["results"])
    assert "reached 4/4 setpoints" in stdout


# The camera swings low round the plant, from its left (y = +0.5 m) to its right (y = -0.44 m):
# fixed joint configurations, not IK results, so no IK branch or seed can change the situation.
SWING_START = np.array([-0.747, -0.805, 1.502, -2.576, -0.988, -0.011])
SWING_GOAL = np.array([0.233, -0.714, 1.747, -2.58, -0.988, -0.011])


def test_example_planner_detours_where_the_straight_line_is_certainly_blocked(site: Path) -> None:
    """The plugin's point: the straight line through the plant fails the built-in ``direct``
    planner, the waypoint planner's detour gets there. Both margins are centimetres: the line
    stays blocked with a keep-out 10 cm thinner, and the detour stays free with 3 cm clearance."""
    install_example(site)
    from agrisim_example_planner import WaypointOptions, WaypointPlanner

    def validity(margin: float = 0.0, **cell: float):
        physics = KinematicPhysics(build_cell(CellConfig(arms=1, **cell)), KinematicOptions(margin=margin))
        return lambda q: not physics.in_collision("r1", q)

    valid = validity()
    kin = ArmKinematics(build_cell(CellConfig(arms=1)).arm("r1"))
    step = MotionConfig().collision_check_step
    assert valid(SWING_START) and valid(SWING_GOAL)
    thinner = validity(keepout_radius=CellConfig().keepout_radius - 0.10)
    blocked = [not thinner(q) for q in segment_samples(SWING_START, SWING_GOAL, step)]
    assert np.mean(blocked) > 0.2  # a fifth of the line inside even the thinner keep-out

    with pytest.raises(PlanningFailed):
        DirectPlanner(NoOptions()).plan(SWING_START, SWING_GOAL, valid, kin.lower, kin.upper, 0, step)
    path = WaypointPlanner(WaypointOptions()).plan(SWING_START, SWING_GOAL, valid, kin.lower, kin.upper, 0, step)
    np.testing.assert_array_equal(path[0], SWING_START)
    np.testing.assert_array_equal(path[-1], SWING_GOAL)
    assert path_is_valid(path, validity(margin=0.03), step / 2)


def test_example_planner_options_are_validated(site: Path, tmp_path: Path, capsys) -> None:
    install_example(site)
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as exc:
        main(
            [
                "run",
                "--physics",
                "kinematic",
                "--planner",
                "waypoint",
                "--set",
                "planner.waypoint.retrat=1",
                "--out",
                str(out),
            ]
        )
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "waypoint" in err and "retrat" in err
    assert not out.exists()


# ---------------------------------------------------------------- registration errors


def test_duplicate_backend_name_names_both_distributions(site: Path, capsys) -> None:
    make_dist(site, "twin-one", {"twin_one": planner_source("twin")}, {"twin-one": "twin_one"})
    make_dist(site, "twin-two", {"twin_two": planner_source("twin")}, {"twin-two": "twin_two"})
    with pytest.raises(PluginError) as exc:
        Registry(make_plugin_manager()).get("planner", "twin")
    assert "'twin'" in str(exc.value)
    assert "twin-one" in str(exc.value) and "twin-two" in str(exc.value)

    code, out, err = plugins_cli(capsys)
    assert code == 2
    assert err.count("\n") == 1 and "twin-one" in err and "twin-two" in err


def test_duplicate_of_a_builtin_name_is_an_error(site: Path) -> None:
    clone = {"direct_clone": planner_source("direct")}
    make_dist(site, "agrisim-direct-clone", clone, {"direct-clone": "direct_clone"})
    with pytest.raises(PluginError) as exc:
        Registry(make_plugin_manager()).specs("planner")
    message = str(exc.value)
    assert (
        "'direct'" in message
        and f"agrisim {agrisim.__version__}" in message
        and "agrisim-direct-clone 0.1.0" in message
    )


def test_entry_point_name_clash_is_not_silent(site: Path) -> None:
    """Two distributions declaring the entry point name agrisim's own uses: pluggy would keep
    whichever it met first, so the registry refuses, naming the entry point and two of them."""
    make_dist(site, "shadow-one", {"shadow_one": planner_source("shadow1")}, {"planner-direct": "shadow_one"})
    make_dist(site, "shadow-two", {"shadow_two": planner_source("shadow2")}, {"planner-direct": "shadow_two"})
    with pytest.raises(PluginError) as exc:
        make_plugin_manager()
    message = str(exc.value)
    assert "'planner-direct'" in message and "declared by both" in message
    assert (
        sum(dist in message for dist in ("shadow-one 0.1.0", "shadow-two 0.1.0", f"agrisim {agrisim.__version__}")) == 2
    )


def test_misspelt_hook_is_an_error(site: Path, capsys) -> None:
    source = """
        from agrisim import BackendSpec, hookimpl

        @hookimpl
        def agrisim_planner():  # should be agrisim_planners
            return []
    """
    make_dist(site, "agrisim-typo", {"agrisim_typo": source}, {"typo": "agrisim_typo"})
    with pytest.raises(PluginError, match="agrisim_planner"):
        make_plugin_manager()

    code, out, err = plugins_cli(capsys)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("agrisim: error: ") and "agrisim_planner" in err and "unknown hook" in err


def test_plugin_that_fails_to_import_is_named(site: Path, capsys) -> None:
    broken = {"agrisim_broken": "raise ImportError('needs libfoo')\n"}
    make_dist(site, "agrisim-broken", broken, {"broken": "agrisim_broken"})
    code, out, err = plugins_cli(capsys)
    assert code == 2
    assert err.count("\n") == 1 and "agrisim-broken" in err and "needs libfoo" in err


def test_provider_returning_garbage_is_named(site: Path) -> None:
    source = """
        from agrisim import hookimpl

        @hookimpl
        def agrisim_planners():
            return ["not a spec"]
    """
    make_dist(site, "agrisim-garbage", {"agrisim_garbage": source}, {"garbage": "agrisim_garbage"})
    with pytest.raises(PluginError, match="agrisim-garbage"):
        Registry(make_plugin_manager()).specs("planner")


# ------------------------------------------------------------------- environment switches


def test_disable_autoload_loads_nothing(site: Path, monkeypatch, capsys) -> None:
    install_example(site)
    monkeypatch.setenv("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "1")
    registry = Registry(make_plugin_manager())
    assert all(registry.specs(kind) == {} for kind in PROVIDER_HOOKS)
    code, out, _ = plugins_cli(capsys)
    assert code == 0
    assert out.count("(none installed)") == len(PROVIDER_HOOKS)
    with pytest.raises(PluginError, match="none installed"):
        registry.get("planner", "direct")


def test_load_plugins_restricts_to_the_named_entry_points(site: Path, monkeypatch, capsys) -> None:
    install_example(site)
    monkeypatch.setenv("AGRISIM_LOAD_PLUGINS", "example-planner, physics-kinematic")
    registry = Registry(make_plugin_manager())
    assert list(registry.specs("planner")) == ["waypoint"]
    assert list(registry.specs("physics")) == ["kinematic"]
    assert registry.specs("sink") == {}
    code, out, _ = plugins_cli(capsys)
    assert code == 0
    assert set(listed(out, "planner")) == {"waypoint"}
    assert set(listed(out, "physics")) == {"kinematic"}


def test_trace_plugins_reports_hook_calls(site: Path, monkeypatch, capsys, tmp_path: Path) -> None:
    """AGRISIM_TRACE_PLUGINS shows what a real run calls: the registry asking each provider for
    its backends, and the event hooks of the episode."""
    monkeypatch.setenv("AGRISIM_TRACE_PLUGINS", "1")
    layer = {
        "physics": {"backend": "kinematic"},
        "planner": {"backend": "direct"},
        "renderer": {"backend": "none"},
        "routine": {"setpoints": "1x1"},
        "cell": {"arms": 1},
        "output": {"out": str(tmp_path / "run"), "no_rrd": True},
    }
    from agrisim.episode import Episode

    Episode(build_config(layer)).run()
    err = capsys.readouterr().err
    assert (
        f"agrisim_planners [agrisim {agrisim.__version__}] -> direct" in err
        and f"agrisim_planners [agrisim {agrisim.__version__}] -> ompl" in err
    )
    assert "agrisim_run_started" in err and "agrisim_setpoint" in err and "agrisim_run_finished" in err


# --------------------------------------------- backend kinds without a built-in backend yet


def test_every_kind_is_discovered_from_a_distribution(site: Path, capsys) -> None:
    """A distribution providing a renderer, a reconstructor and a plant shows up under each
    kind with its distribution."""
    source = """
        from agrisim import BackendSpec, hookimpl
        from agrisim.interfaces import PlantSpecies, Reconstructor, Renderer

        class FakeRenderer(Renderer):
            def render(self, camera, world_T_camera, link_poses):
                return None

        class FakeReconstructor(Reconstructor):
            def integrate(self, view):
                return {}

            def merged(self):
                return {}

            def result(self):
                return None

        class FakePlant(PlantSpecies):
            def build(self, seed):
                return seed

        @hookimpl
        def agrisim_renderers():
            return [BackendSpec(name="fake-render", factory=FakeRenderer, description="renders nothing")]

        @hookimpl
        def agrisim_reconstructors():
            return [BackendSpec(name="fake-recon", factory=FakeReconstructor, description="keeps nothing")]

        @hookimpl
        def agrisim_plants():
            return [BackendSpec(name="fake-plant", factory=FakePlant, description="grows nothing")]
    """
    make_dist(site, "agrisim-fakes", {"agrisim_fakes": source}, {"fakes": "agrisim_fakes"}, version="2.0")
    registry = Registry(make_plugin_manager())
    construct = {"renderer": (None, None, None, None), "reconstructor": (None, None), "plant": (None,)}
    abcs = {"renderer": Renderer, "reconstructor": Reconstructor, "plant": PlantSpecies}
    for kind, name in (("renderer", "fake-render"), ("reconstructor", "fake-recon"), ("plant", "fake-plant")):
        spec = registry.get(kind, name)
        assert spec.distribution == "agrisim-fakes 2.0"
        built = registry.build(kind, spec, *construct[kind])  # checked against the kind's ABC
        assert isinstance(built, abcs[kind]) and type(built).__module__ == "agrisim_fakes"
    code, out, _ = plugins_cli(capsys)
    assert code == 0
    assert "[agrisim-fakes 2.0]" in listed(out, "reconstructor")["fake-recon"]
    assert "[agrisim-fakes 2.0]" in listed(out, "plant")["fake-plant"]
    assert "[agrisim-fakes 2.0]" in listed(out, "renderer")["fake-render"]


# --------------------------------------------------------------------------- events


class Recorder:
    """Records every event hook call of one run."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, dict]] = []

    @agrisim.hookimpl
    def agrisim_run_started(self, run):
        self.calls.append(("agrisim_run_started", {"run": run}))

    @agrisim.hookimpl
    def agrisim_trajectory(self, run, robot, trajectory):
        self.calls.append(("agrisim_trajectory", {"robot": robot, "trajectory": trajectory}))

    @agrisim.hookimpl
    def agrisim_setpoint(self, run, robot, result):
        self.calls.append(("agrisim_setpoint", {"robot": robot, "result": result}))

    @agrisim.hookimpl
    def agrisim_capture(self, run, capture):
        self.calls.append(("agrisim_capture", {"capture": capture}))

    @agrisim.hookimpl
    def agrisim_cloud(self, run, label, cloud, merged):
        self.calls.append(("agrisim_cloud", {"label": label, "merged": merged}))

    @agrisim.hookimpl
    def agrisim_run_finished(self, run, summary):
        self.calls.append(("agrisim_run_finished", {"summary": summary}))


def test_event_hooks_fire_in_order(site: Path, tmp_path: Path, monkeypatch) -> None:
    from agrisim.episode import Episode

    # a robot-only run still checks the plant it names: the species' plugin is needed too
    monkeypatch.setenv("AGRISIM_LOAD_PLUGINS", "physics-kinematic,planner-direct,plants-procedural")
    pm = make_plugin_manager()
    recorder = Recorder()
    pm.register(recorder)
    config = build_config(
        {
            "physics": {"backend": "kinematic"},
            "planner": {"backend": "direct"},
            "routine": {"setpoints": "1x1"},
            "cell": {"arms": 1},
            "renderer": {"backend": "none"},
            "output": {"out": str(tmp_path / "run"), "no_rrd": True},
        }
    )
    run, summary = Episode(config, pm).run()
    names = [name for name, _ in recorder.calls]
    assert names == [
        "agrisim_run_started",
        "agrisim_trajectory",
        "agrisim_capture",
        "agrisim_setpoint",
        "agrisim_run_finished",
    ]
    assert summary.reached == 1 and summary.status == "complete"
    capture = recorder.calls[2][1]["capture"]
    assert capture.frame == "r1_000" and capture.world_T_camera.shape == (4, 4)
    assert recorder.calls[-1][1]["summary"] is summary


# ------------------------------------------------------------------------ meta-tests

#: hooks with no built-in implementation yet -> the test above that exercises them
EXERCISED_BY_TESTS = {
    "agrisim_renderers": test_every_kind_is_discovered_from_a_distribution,
    "agrisim_reconstructors": test_every_kind_is_discovered_from_a_distribution,
    "agrisim_plants": test_every_kind_is_discovered_from_a_distribution,
    "agrisim_planners": test_example_package_is_discovered_with_its_distribution,
    "agrisim_run_started": test_event_hooks_fire_in_order,
    "agrisim_trajectory": test_event_hooks_fire_in_order,
    "agrisim_setpoint": test_event_hooks_fire_in_order,
    "agrisim_capture": test_event_hooks_fire_in_order,
    "agrisim_run_finished": test_event_hooks_fire_in_order,
}


def _hookspecs() -> dict[str, object]:
    return {
        name: fn for name, fn in vars(hookspecs).items() if callable(fn) and hasattr(fn, f"{hookspecs.PROJECT}_spec")
    }


#: libraries of optional extras that a backend's submodules may import (not installed in CI)
OPTIONAL_LIBRARIES = {"torch", "gsplat"}


def _builtin_implementations() -> set[str]:
    """Hooks implemented anywhere in agrisim's own entry-point modules (module functions and
    methods of the classes they define, e.g. the sinks' per-run objects), and by the commands
    the CLI host registers itself (agrisim.plugins.apps.commands)."""
    import importlib
    from importlib import metadata

    marker = f"{hookspecs.PROJECT}_impl"
    found: set[str] = set()
    for ep in metadata.distribution("agrisim").entry_points:
        if ep.group != hookspecs.PROJECT:
            continue
        root = importlib.import_module(ep.module)
        modules = [root]
        if hasattr(root, "__path__"):  # a backend package: its submodules define the classes
            for m in pkgutil.walk_packages(root.__path__, f"{root.__name__}."):
                try:
                    modules.append(importlib.import_module(m.name))
                except ModuleNotFoundError as exc:  # an optional extra's library (splat: PyTorch)
                    if exc.name not in OPTIONAL_LIBRARIES:
                        raise
        for module in modules:
            _hook_names(module, marker, found)
    _hook_names(importlib.import_module("agrisim.plugins.apps.commands"), marker, found)
    return found


def _hook_names(module: Any, marker: str, found: set[str]) -> None:
    """Add the hooks ``module`` implements: its functions and its classes' methods."""
    for obj in vars(module).values():
        if callable(obj) and hasattr(obj, marker):
            found.add(obj.__name__)
        if inspect.isclass(obj) and obj.__module__ == module.__name__:
            found.update(n for n, m in vars(obj).items() if callable(m) and hasattr(m, marker))


def test_every_hookspec_is_documented() -> None:
    specs = _hookspecs()
    assert set(PROVIDER_HOOKS.values()) <= set(specs)
    for name, fn in specs.items():
        doc = inspect.getdoc(fn) or ""
        assert len(doc.split()) >= 5, f"hookspec {name} has no real docstring"


def test_every_hook_is_implemented_or_tested() -> None:
    builtin = _builtin_implementations()
    untested = sorted(name for name in _hookspecs() if name not in builtin and name not in EXERCISED_BY_TESTS)
    assert not untested, f"hooks neither implemented by a built-in plugin nor exercised by a test: {untested}"
    assert not set(EXERCISED_BY_TESTS) - set(_hookspecs()), "EXERCISED_BY_TESTS names a hook that no longer exists"
    assert all(fn.__name__ in globals() for fn in EXERCISED_BY_TESTS.values())


# ------------------------------------------------------------------ the Options base


def test_options_base_refuses_unknown_keys_and_bools_for_numbers() -> None:
    from pydantic import ValidationError

    class Lift(agrisim.Options):
        height: float = 0.5
        """How high, m."""
        tries: int = 3
        """How many times."""
        limit: float | None = None
        """An optional bound, m."""
        loud: bool = False
        """Say so."""

    assert Lift(height=1, tries=2, limit=0.2, loud=True).height == 1.0
    assert Lift.model_fields["height"].description == "How high, m."
    for bad in ({"hieght": 1.0}, {"height": True}, {"tries": False}, {"limit": True}):
        with pytest.raises(ValidationError):
            Lift(**bad)


def test_every_builtin_backend_takes_agrisim_options() -> None:
    registry = Registry(make_plugin_manager())
    for kind in PROVIDER_HOOKS:
        for spec in registry.specs(kind).values():
            assert issubclass(spec.options_model, agrisim.Options), (kind, spec.name)


# ------------------------------------------------------------------ capabilities


def test_capabilities_of_the_wrong_kind_name_the_plugin(site: Path) -> None:
    source = """
        from agrisim import BackendSpec, hookimpl
        from agrisim.capabilities import PhysicsCapabilities
        from agrisim.plugins.planners.direct import DirectPlanner

        @hookimpl
        def agrisim_renderers():
            return [BackendSpec(name="odd", factory=DirectPlanner, description="x", capabilities=PhysicsCapabilities())]
    """
    make_dist(site, "agrisim-odd-caps", {"odd_caps": source}, {"odd-caps": "odd_caps"})
    with pytest.raises(PluginError) as exc:
        Registry(make_plugin_manager()).specs("renderer")
    message = str(exc.value)
    assert "'odd'" in message and "agrisim-odd-caps 0.1.0" in message and "RendererCapabilities" in message


def test_a_renderer_that_declares_nothing_gets_the_least(site: Path) -> None:
    """Undeclared capabilities promise the least: texture labels only, so asking such a
    renderer for organs is refused before anything is built."""
    source = """
        from agrisim import BackendSpec, hookimpl
        from agrisim.plugins.planners.direct import DirectPlanner

        @hookimpl
        def agrisim_renderers():
            return [BackendSpec(name="plain", factory=DirectPlanner, description="x")]
    """
    make_dist(site, "agrisim-plain", {"plain_renderer": source}, {"plain": "plain_renderer"})
    from agrisim.capabilities import RendererCapabilities, check_renderer

    registry = Registry(make_plugin_manager())
    spec = registry.get("renderer", "plain")
    assert spec.capabilities == RendererCapabilities()
    check_renderer(spec, registry.specs("renderer"), ["texture"], "plant")  # within what it declares
    with pytest.raises(UserError, match="'plain' cannot draw organ labels.*renderers that can: mitsuba, raycast"):
        check_renderer(spec, registry.specs("renderer"), ["texture"], "organs")


def test_the_pybullet_renderer_is_accepted_for_what_it_declares(tmp_path: Path) -> None:
    from agrisim.episode import Episode

    layer = {
        "renderer": {"backend": "pybullet"},
        "render": {"seg_mode": "repopa"},
        "output": {"out": str(tmp_path / "r")},
    }
    episode = Episode(build_config(layer))  # validated, nothing written
    assert episode.renderer_spec.name == "pybullet" and not (tmp_path / "r").exists()


def test_a_factory_returning_the_wrong_type_names_the_plugin(site: Path) -> None:
    source = """
        from agrisim import BackendSpec, hookimpl

        @hookimpl
        def agrisim_planners():
            return [BackendSpec(name="dud", factory=lambda options: object(), description="returns nothing useful")]
    """
    make_dist(site, "agrisim-dud", {"agrisim_dud": source}, {"dud": "agrisim_dud"}, version="0.3")
    registry = Registry(make_plugin_manager())
    with pytest.raises(BackendFailure) as exc:
        registry.build("planner", registry.get("planner", "dud"), NoOptions())
    message = str(exc.value)
    assert "'dud'" in message and "agrisim-dud 0.3" in message and "agrisim.interfaces.Planner" in message


def test_the_kind_table_names_real_hooks_sections_and_abcs() -> None:
    """One table of kinds: each hook is a hookspec, each section a configuration table that
    chooses a backend, each ABC from agrisim.interfaces."""
    from agrisim.config import BackendChoice, RunConfig
    from agrisim.kinds import KINDS

    for kind, info in KINDS.items():
        assert hasattr(hookspecs, info.hook), kind
        if info.section is not None:
            assert issubclass(RunConfig.model_fields[info.section].annotation, BackendChoice), kind
        if info.abc is not None:
            assert isinstance(info.abc, type) and info.abc.__module__ == "agrisim.interfaces", kind
        doc = hookspecs.__dict__[info.hook].__doc__ or ""
        assert "factory(" in doc or kind == "sink", f"hookspec {info.hook} does not document the factory"
