"""The web viewer's default layout for the README (``docs/web_viewer.png``): a small run's
recording served as ``agrisim view`` serves it, screenshot by the headless Chromium the tests
drive (``tests/browser.py``, WebGL on its CPU rasterizer), once the page passes the same check as
``tests/e2e/test_web_view.py``. Run: ``python bench/figure_viewer.py [OUT.png]``."""

from __future__ import annotations

import socket
import sys
import tempfile
from pathlib import Path

from PIL import Image

from agrisim.config import build_config
from agrisim.episode import Episode
from agrisim.plugins.apps.web import serve_web

TESTS = Path(__file__).resolve().parent.parent / "tests"
sys.path[:0] = [str(TESTS), str(TESTS / "e2e")]
from browser import Page  # noqa: E402 - found through the sys.path set above
from test_web_view import TIMELINE_NOTICE, shows_photographs, shows_views  # noqa: E402

#: the page as the test sees it, then scaled down for the README
PAGE = (1600, 900)
FIGURE = (1200, 675)
#: a screenshot is flat UI colour and a few rendered panels: a palette keeps it small
COLOURS = 256


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def record(out: Path) -> Path:
    """A small complete run with its recording: 1x3 views per arm, kinematic arms, 640x360."""
    config = build_config(
        {
            "renderer": {"raycast": {"shadow_samples": 0}},
            "physics": {"backend": "kinematic"},
            "routine": {"setpoints": "1x3"},
            "camera": {"resolution": "640x360"},
            "output": {"out": str(out), "no_rrd": False},
        }
    )
    _, summary = Episode(config).run()
    if summary.status != "complete":
        raise RuntimeError(f"the run did not complete: {summary.status}")
    return out / "recording.rrd"


def main(path: Path) -> None:
    with tempfile.TemporaryDirectory(prefix="agrisim-figure-") as tmp:
        recording = record(Path(tmp) / "run")
        viewer = serve_web(recording, web_port=free_port(), grpc_port=free_port())
        with viewer, Page(viewer.url, *PAGE) as page:
            shot = page.wait_for(shows_views, timeout=300)
            notices = [text for level, text in page.console_lines() if level in ("warning", "error")]
    # a figure of a page that fails the test's checks would show what the README says it does not
    if not (shows_views(shot) and shows_photographs(shot)):
        raise RuntimeError("the viewer did not show its 3D, camera and depth views in time")
    if any(TIMELINE_NOTICE.search(n) for n in notices):
        raise RuntimeError(f"the viewer noticed a missing timeline: {notices}")
    image = Image.fromarray(shot).resize(FIGURE, Image.Resampling.LANCZOS)
    path.parent.mkdir(parents=True, exist_ok=True)
    image.quantize(COLOURS, dither=Image.Dither.NONE).save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/web_viewer.png"))
