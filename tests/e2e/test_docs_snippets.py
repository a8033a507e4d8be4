"""Every Python snippet of the README and the docs runs, as pytest-markdown-docs runs them
(each in a folder of its own; the fixtures a fence names are in the repository's conftest.py).
They run in a pytest of their own: ``--markdown-docs`` would also collect every Python file
of tests/ for its docstrings, helpers that are not tests among them."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_every_python_snippet_runs() -> None:
    sources = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
    fences = sum(len(re.findall(r"^```(?:python|\{\.python[^}]*\})\s*$", p.read_text(), re.M)) for p in sources)
    assert fences >= 8
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", "--markdown-docs",
         "--markdown-docs-syntax=superfences", "README.md", "docs"],
        cwd=REPO,
        capture_output=True,
        text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-6000:]
    assert re.search(rf"\b{fences} passed\b", done.stdout), done.stdout[-2000:]
