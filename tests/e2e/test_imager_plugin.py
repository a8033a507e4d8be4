"""A third-party imager, the way its author ships it: ``mono8`` of the test package
``tests/e2e/agrisim-mono-imager`` (a monochrome camera), installed as a distribution into a
temporary folder on ``sys.path``, found through the ``agrisim`` entry points beside the
built-in ``imx708`` and ``ov2740``, held to the imager contract, and chosen by ``--imager`` for
a run: every view on disk is its grey (R = G = B) at its fixed exposure, which the run records."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import installed
from PIL import Image

from agrisim.registry import Registry, make_plugin_manager
from agrisim.testing.contracts import check

PACKAGE = Path(__file__).resolve().parent / "agrisim-mono-imager"


@pytest.fixture
def site(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The test package installed in a fresh folder on ``sys.path``; forgotten afterwards."""
    with installed(PACKAGE, tmp_path / "site", monkeypatch):
        yield tmp_path / "site"


def test_it_is_listed_and_keeps_the_imager_contract(site: Path, cli) -> None:  # noqa: ANN001
    code, out, _ = cli(["plugins"])
    assert code == 0
    imagers = out[out.index("imager:") : out.index("planner:")]
    assert "mono8" in imagers and "[agrisim-mono-imager 0.1.0]" in imagers and "imx708" in imagers
    check("imager", "mono8", Registry(make_plugin_manager()))
    code, out, err = cli(["run", "--imager", "mono9", "--out", str(site / "never")])
    assert code == 2 and "imagers: none, imx708, mono8, ov2740" in err and not (site / "never").exists()


def test_a_run_shoots_through_it(site: Path, tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "run"
    args = ["run", "--physics", "kinematic", "--setpoints", "1x2", "--resolution", "96x54", "--recon", "none"]
    code, _, err = cli([*args, "--imager", "mono8", "--shadow-samples", "0", "--no-rrd", "--out", str(out)])
    assert code == 0, err
    cameras = json.loads((out / "cameras.json").read_text())
    assert cameras["imager"]["name"] == "mono8"
    frames = cameras["frames"]
    assert len(frames) == 4
    for name, frame in frames.items():
        assert frame["exposure"]["time_s"] == 0.004 and frame["exposure"]["analogue_gain"] == 1.0
        rgb = np.asarray(Image.open(out / "rgb" / f"{name}.png"))
        assert rgb.shape == (54, 96, 3)
        assert np.array_equal(rgb[..., 0], rgb[..., 1]) and np.array_equal(rgb[..., 1], rgb[..., 2]), name
        assert rgb.std() > 5  # a picture, not a flat grey
