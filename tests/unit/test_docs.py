"""The front door and the documentation's text: the README is short and points into the pages,
every shell snippet of README and docs is a command line agrisim's own parser accepts, nothing
that left the README was lost, the version is one everywhere, and every package goes into the
wheel. (The site's build, its CLI page and its search: tests/e2e/test_docs_site.py; the Python
snippets run as tests themselves: ``pytest --markdown-docs``, in ``make test``.)"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # the lock's tomli on 3.10
    import tomli as tomllib

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted((REPO / "docs").rglob("*.md"))
#: the README before it became a front door (the commit before the split): what it held must
#: still be somewhere
BEFORE_SPLIT = "d41dc5d"
FENCE = re.compile(r"^```([^\n]*)\n(.*?)^```", re.M | re.S)


def _markdown() -> dict[Path, str]:
    return {p: p.read_text() for p in [REPO / "README.md", *PAGES]}


def test_the_readme_is_a_front_door() -> None:
    """At most 250 lines, with the two commands and links into the pages that all exist."""
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    assert "make run" in readme and "make test" in readme and "make docs" in readme
    links = re.findall(r"\]\((docs/[^)#\s]+)", readme)
    assert len(links) >= 20
    missing = [link for link in links if not (REPO / link).exists()]
    assert not missing, f"README links to missing pages: {missing}"


def _commands(text: str) -> list[tuple[str, list[str]]]:
    """Every ``agrisim ...`` line of the shell fences in ``text`` (continuations joined,
    comments and prompts dropped), with its arguments: ``[opts]``-style placeholders dropped,
    ``a|b`` read as ``a``."""
    out = []
    for info, body in FENCE.findall(text):
        if info.strip().lstrip("{.").split(" ")[0] not in ("sh", "bash", "console", "shell"):
            continue
        for line in body.replace("\\\n", " ").splitlines():
            line = line.strip().removeprefix("$ ")
            if not line.startswith("agrisim "):
                continue
            words = shlex.split(line, comments=True)[1:]
            args = []
            for word in words:
                if word.startswith("[") or word in ("...", "&") or word.endswith("]"):
                    continue
                args.append(word.split("|")[0] if "|" in word and not word.startswith("-") else word)
            out.append((line, args))
    return out


def test_every_shell_snippet_is_a_command_agrisim_accepts() -> None:
    """The docs' command lines parse with agrisim's own parser (run, they would be checked
    further; parsing is what a typo in a flag or a command fails)."""
    from agrisim.app.arguments import build_parser

    seen = 0
    for path, text in _markdown().items():
        for line, args in _commands(text):
            seen += 1
            try:
                build_parser().parse_args(args)
            except SystemExit as exc:
                pytest.fail(f"{path.relative_to(REPO)}: {line!r} is refused by agrisim's parser ({exc.code})")
    assert seen >= 40  # the snippets were found at all


def test_a_shell_snippet_with_a_wrong_flag_is_caught() -> None:
    """The check above can fail: a flag agrisim does not have is refused."""
    from agrisim.app.arguments import build_parser

    ((line, args),) = _commands("```sh\nagrisim run --plnat coltsfoot  # a typo\n```\n")
    with pytest.raises(SystemExit):
        build_parser().parse_args(args)


def _old_readme() -> str:
    try:
        return subprocess.run(
            ["git", "show", f"{BEFORE_SPLIT}:README.md"], cwd=REPO, capture_output=True, text=True, check=True
        ).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip(f"no git history with {BEFORE_SPLIT} (a shallow clone or an sdist)")


def test_what_left_the_readme_is_on_a_page() -> None:
    """Every figure, table (by its header row) and section heading the README had before it
    became a front door is in the README or on a page of the site."""
    old = _old_readme()
    now = "\n".join(_markdown().values())
    images = {Path(m).name for m in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", old)}
    lost = [name for name in images if name not in now]
    assert not lost, f"figures no page shows: {lost}"
    fence = False
    headers, headings = [], []
    lines = old.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("```"):
            fence = not fence
        elif not fence and line.startswith("|") and i + 1 < len(lines) and lines[i + 1].startswith("|---"):
            headers.append(line)
        elif not fence and re.match(r"#{2,4} ", line):
            headings.append(line.lstrip("#").strip())
    assert len(headers) > 30 and len(headings) > 30
    assert not [h for h in headers if h not in now], "tables no page holds"
    assert not [h for h in headings if not re.search(rf"^#+ {re.escape(h)}$", now, re.M)], "sections no page holds"


def test_one_version_everywhere() -> None:
    """pyproject.toml, agrisim.__version__, ``agrisim --version`` and the changelog's newest
    entry name the same version."""
    import agrisim

    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert agrisim.__version__ == version
    printed = subprocess.run(
        [sys.executable, "-m", "agrisim", "--version"], capture_output=True, text=True, check=True
    ).stdout
    assert printed.strip() == f"agrisim {version}"
    newest = re.search(r"^## (\S+)", (REPO / "docs" / "changelog.md").read_text(), re.M)
    assert newest is not None and newest.group(1) == version


def test_every_package_goes_into_the_wheel() -> None:
    """pyproject.toml lists every folder of core/, testing/ and plugins/ that is a package (a package
    left out installs fine in editable mode and is missing from the wheel)."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text())
    listed = set(project["tool"]["setuptools"]["packages"])
    found = set()
    for folder, name in (("core", "agrisim"), ("testing", "agrisim.testing"), ("plugins", "agrisim.plugins")):
        for init in (REPO / folder).rglob("__init__.py"):
            parts = init.parent.relative_to(REPO / folder).parts
            found.add(".".join((name, *parts)))
    assert listed == found, f"missing {sorted(found - listed)}, extra {sorted(listed - found)}"
