"""Fixtures of the documentation's Python snippets, which run as tests (``pytest --markdown-docs
--markdown-docs-syntax=superfences README.md docs``, part of ``make test``): each runs in a
folder of its own, so a snippet's ``runs/demo`` never meets another's; a snippet that reads a
run says so in its fence (```` ```{.python fixture:coco_run} ````)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _snippet_in_its_own_folder(request: pytest.FixtureRequest, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if type(request.node).__name__ == "MarkdownInlinePythonItem":  # pytest-markdown-docs' items only
        monkeypatch.chdir(tmp_path)


@pytest.fixture
def coco_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """``RUN/``, a small run with its COCO export, in the snippet's folder."""
    from agrisim import Episode, build_config
    from agrisim.app.cli import main

    monkeypatch.chdir(tmp_path)
    config = build_config(
        {
            "plant": "coltsfoot",
            "routine": {"setpoints": "1x2"},
            "camera": {"resolution": "160x90"},
            "physics": {"backend": "kinematic"},
            "output": {"out": "RUN", "no_rrd": True},
        }
    )
    Episode(config).run()
    assert main(["export", "coco", "RUN"]) == 0
    return tmp_path / "RUN"
