"""A third-party command, the way its author ships it: ``agrisim frames`` of the test package
``tests/e2e/agrisim-frames-command``, installed as a distribution into a temporary folder on
``sys.path`` (its module, a dist-info with its entry points), found through the ``agrisim``
entry points, listed by ``agrisim --help`` after agrisim's own commands (which register through
the same hook) and run. The truth: the run's ``cameras.json`` read here by other means. A
command named twice is refused, naming both plugins."""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import installed

from agrisim.plugins.apps.commands import ORDER

PACKAGE = Path(__file__).resolve().parent / "agrisim-frames-command"


def install(root: Path, name: str, version: str, points: dict[str, str], modules: dict[str, str]) -> None:
    """A distribution as pip lays it out: its modules and a dist-info with its entry points."""
    info = root / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text("[agrisim]\n" + "".join(f"{k} = {v}\n" for k, v in points.items()))
    for module, text in modules.items():
        (root / f"{module}.py").write_text(text)


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The test package installed in a fresh folder on ``sys.path``; forgotten afterwards."""
    with installed(PACKAGE, tmp_path / "site", monkeypatch):
        yield tmp_path / "site"
    sys.modules.pop("agrisim_run_again", None)  # (installed beside it by a test)


def test_a_plugins_command_runs_on_a_run(site: Path, saved_runs, cli) -> None:  # noqa: ANN001
    run = saved_runs.get()
    truth = json.loads((run / "cameras.json").read_text())["frames"]
    code, out, err = cli(["frames", str(run), "--json"])
    assert code == 0, err
    centres = json.loads(out)
    assert sorted(centres) == sorted(truth)
    for name, centre in centres.items():
        np.testing.assert_allclose(centre, np.asarray(truth[name]["world_T_camera"])[:3, 3], atol=1e-6)
    code, out, _ = cli(["frames", str(run), "--arm", "r2"])
    assert code == 0 and out.splitlines()[0] == f"r2: {sum(n.startswith('r2_') for n in truth)} views"
    code, out, err = cli(["frames", str(run), "--arm", "r9"])
    assert code == 2 and not out and err == "agrisim: error: --arm 'r9': the run's arms are r1, r2\n"


def test_help_lists_it_after_agrisims_own(site: Path, cli) -> None:  # noqa: ANN001
    code, out, _ = cli(["--help"])
    assert code == 0
    listed = re.findall(r"^    (\w+)\s", out, re.M)
    assert listed == [*ORDER, "frames"]
    assert "a run's views, arm by arm, with each camera's centre" in out
    code, out, _ = cli(["frames", "--help"])
    assert code == 0 and "--arm NAME" in out and "List the views of a run directory" in out


def test_a_command_added_twice_is_refused_naming_both(site: Path, cli) -> None:  # noqa: ANN001
    again = (
        "from agrisim.commands import Command\nfrom agrisim.registry import hookimpl\n\n"
        "@hookimpl\ndef agrisim_commands():\n    return [Command('run', help='x', add_arguments=print, run=len)]\n"
    )
    install(site, "agrisim-run-again", "0.1.0", {"run-again": "agrisim_run_again"}, {"agrisim_run_again": again})
    code, out, err = cli(["plugins"])
    assert code == 2 and not out
    assert err == "agrisim: error: the command 'run' is added by both agrisim and run-again\n"


@pytest.mark.parametrize(
    ("switch", "value"),
    [("AGRISIM_LOAD_PLUGINS", "physics-kinematic"), ("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "1")],
)
def test_agrisims_own_commands_stay_whatever_plugins_are_chosen(  # noqa: ANN001
    site: Path, cli, monkeypatch: pytest.MonkeyPatch, switch: str, value: str
) -> None:
    """The switches that choose a run's backends leave agrisim's own commands (an entry point of
    agrisim's distribution, ``apps``) in place, and leave a third party's out."""
    monkeypatch.setenv(switch, value)
    code, out, _ = cli(["--help"])
    assert code == 0
    assert re.findall(r"^    (\w+)\s", out, re.M) == list(ORDER)
    code, out, err = cli(["plugins"])
    assert code == 0, err
    assert ("kinematic" in out) == (switch == "AGRISIM_LOAD_PLUGINS") and "raycast" not in out
