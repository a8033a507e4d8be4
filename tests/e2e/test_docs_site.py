"""The documentation site as its readers get it: ``mkdocs build --strict`` succeeds (a broken
link, anchor or API reference fails it), the generated CLI page says exactly what ``agrisim
COMMAND --help`` says, and in a real headless browser the site's search for "COCO" leads to the
export guide."""

from __future__ import annotations

import functools
import html
import http.server
import json
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from browser import Page, browser  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
QUIET = {"NO_MKDOCS_2_WARNING": "1", "DISABLE_MKDOCS_2_WARNING": "true"}


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    build = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=REPO,
        capture_output=True,
        text=True,
        env={**os.environ, **QUIET},
    )
    assert build.returncode == 0, build.stderr[-4000:]
    return out


def _blocks(page: Path) -> list[str]:
    """The text of every code block of a built page."""
    return [
        html.unescape(re.sub(r"<[^>]+>", "", block))
        for block in re.findall(r"<pre[^>]*>.*?<code>(.*?)</code>", page.read_text(), re.S)
    ]


#: prints ``agrisim COMMAND --help`` for each command given as JSON, as the ``agrisim`` entry point
#: does (its own ``main``; argparse exits after printing), each followed by a separator line
HELPS = """
import contextlib, io, json, sys
from agrisim.app.cli import main
for command in json.loads(sys.argv[1]):
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed), contextlib.suppress(SystemExit):
        main([*command, "--help"])
    print(printed.getvalue() + "\\f")
"""


def test_the_cli_page_is_what_help_prints(site: Path) -> None:
    """Each subcommand's block on the CLI page equals its ``--help`` (at the page's width).
    (One interpreter prints them all: a process a command cost a second each.)"""
    from agrisim.app.arguments import build_parser

    blocks = _blocks(site / "reference" / "cli" / "index.html")
    commands = [[]] + [[name] for name in build_parser()._subparsers._group_actions[0].choices]  # type: ignore[union-attr]
    assert len(blocks) == len(commands)
    printed = subprocess.run(
        [sys.executable, "-c", HELPS, json.dumps(commands)],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "COLUMNS": "100"},
    ).stdout.split("\f\n")[:-1]
    assert len(printed) == len(commands)
    for block, command, text in zip(blocks, commands, printed, strict=True):
        assert block.strip() == text.strip(), f"agrisim {' '.join(command)} --help differs from the page"


def test_the_api_reference_renders_the_docstrings(site: Path) -> None:
    """The API pages hold the docstrings themselves (mkdocstrings found the package)."""
    from agrisim.episode import Episode

    text = html.unescape(re.sub(r"<[^>]+>", "", (site / "reference" / "api" / "agrisim" / "index.html").read_text()))
    first = (Episode.__doc__ or "").strip().splitlines()[0]
    assert first and first in text
    # the docstrings' reST (roles, double backticks) arrives as Markdown code, not raw
    pages = [p.read_text() for p in (site / "reference" / "api").rglob("index.html")]
    assert len(pages) >= 11 and not [p for p in pages if ":class:`" in p or ":meth:`" in p or "``" in p]


@pytest.fixture
def served(site: Path) -> Iterator[str]:
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args: object) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(site)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()


def _js(page: Page, expression: str) -> object:
    """``expression``'s value in the page (None while the page is navigating away)."""
    try:
        reply = page.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, page.session)
    except RuntimeError as exc:
        if "navigated" in str(exc):
            return None
        raise
    return reply["result"].get("value")


def _until(page: Page, expression: str, timeout: float = 60.0) -> object:
    deadline = time.monotonic() + timeout
    while True:
        value = _js(page, expression)
        if value or time.monotonic() > deadline:
            return value
        time.sleep(0.5)


@pytest.mark.skipif(
    browser() is None and not os.environ.get("CI"), reason="no headless Chromium (make test installs it)"
)
def test_searching_coco_lands_on_the_export_guide(served: str) -> None:
    """Type "COCO" into the site's search box as a reader would, open the first result: it is
    the exports guide."""
    with Page(served, width=1280, height=800) as page:
        assert _until(page, "document.readyState === 'complete' && !!document.querySelector('.md-search__input')")
        # the search's worker has its index once the results' line no longer says "Initializing
        # search" (Material's search.result.initializer): typed before that, a query is lost
        meta = "(document.querySelector('.md-search-result__meta') || {}).textContent || 'Initializing'"
        assert _until(page, f"!/Initializing/.test({meta})", 120.0), "the site's search never had its index"
        first: object = ""
        for _ in range(4):  # typed before the search's worker has its index, a query is lost: type again
            _js(page, "(q => { q.value = ''; q.focus(); })(document.querySelector('.md-search__input'))")
            # key by key, as a reader types: Material's search reads the query on each key's
            # release (text inserted without keys is in the box, but never searched)
            for key in "COCO":
                page.call("Input.dispatchKeyEvent", {"type": "keyDown", "key": key, "text": key}, page.session)
                page.call("Input.dispatchKeyEvent", {"type": "keyUp", "key": key}, page.session)
            first = _until(page, "(document.querySelector('.md-search-result__item a') || {}).href || ''", 15.0)
            if first:
                break
        state = "[document.querySelector('.md-search__input').value, (document.querySelector('.md-search-result__meta') || {}).textContent].join(' | ')"
        assert first, f"the search listed nothing for COCO (query | results: {_js(page, state)})"
        _js(page, "document.querySelector('.md-search-result__item a').click()")
        landed = _until(page, "location.pathname.includes('/guides/') ? location.pathname : ''")
        # the new page's heading, once it has loaded (the path changes first)
        title = _until(
            page,
            "document.readyState === 'complete' && document.querySelector('h1') ? document.querySelector('h1').textContent : ''",
        )
    assert landed == "/guides/exports/", (first, landed, title)
    assert "Exports" in str(title)
