"""``agrisim view`` and ``agrisim run --serve-web``: the recording served to a real headless
browser (Debian's Chromium, WebGL on its CPU rasterizer), whose screenshot must show the 3D view,
the cameras' photographs (no colour map over them) and their depth panels, with no "Timeline ...
not found" notice from the viewer; loopback only by default; Ctrl-C stops cleanly; bad addresses
refused."""

from __future__ import annotations

import contextlib
import os
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from browser import Page, browser
from PIL import Image

pytestmark = pytest.mark.skipif(
    browser() is None and not os.environ.get("CI"), reason="no headless Chromium (make test installs it)"
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def listening_addresses(port: int) -> set[str]:
    """The local IPv4 addresses listening on ``port`` (from /proc/net/tcp, state 0A)."""
    out = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        address, hex_port = local.split(":")
        if state == "0A" and int(hex_port, 16) == port:
            out.add(socket.inet_ntoa(bytes.fromhex(address)[::-1]))
    return out


#: what the viewer logs when its blueprint selects a timeline the recording holds no row on
TIMELINE_NOTICE = re.compile(r"Timeline .* not found")


def colourful(pixels: np.ndarray) -> np.ndarray:
    s = pixels.astype(int)
    return (s.max(axis=2) - s.min(axis=2)) > 60


def panels(shot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The default layout's 3D view, cameras and depth panels in a 1600 x 900 page, or None
    before the depth panels show. The 3D view is the left two thirds, the cameras and their
    depth panels the right column, found by the depth panels: the longest run of rows that a
    colour map covers (their height depends on the time panel's)."""
    h, w = shot.shape[:2]
    top = int(0.07 * h)
    right = shot[:, int(0.59 * w) : int(0.80 * w)]
    mapped = np.flatnonzero(colourful(right).mean(axis=1) > 0.9)
    if len(mapped) == 0:
        return None
    runs = np.split(mapped, np.flatnonzero(np.diff(mapped) > 1) + 1)
    depth = max(runs, key=len)
    if len(depth) < 0.05 * h or depth[0] < top + 0.1 * h:
        return None
    view3d = shot[top : depth[-1], int(0.13 * w) : int(0.57 * w)]
    return view3d, right[top : depth[0] - 5], right[depth[0] : depth[-1] + 1]


def shows_views(shot: np.ndarray) -> bool:
    """Does the viewer show content in its 3D view (coloured meshes), its camera views (the
    plant, green) and its depth views (a colour map)? A loading or empty viewer is all grey."""
    found = panels(shot)
    if found is None:
        return False
    view3d, cameras, _ = found
    s = cameras.astype(int)
    green = (s[..., 1] > s[..., 0] + 40) & (s[..., 1] > s[..., 2] + 40)
    return bool(colourful(view3d).mean() > 0.005 and colourful(cameras).mean() > 0.05 and green.mean() > 0.01)


def shows_photographs(shot: np.ndarray) -> bool:
    """Are the camera panels photographs rather than colour maps over them? The lab's
    photograph is mostly grey (floor, walls, table): measured, 71% of the panels' pixels within
    20 levels of grey; with a depth map blended over it, 6%."""
    found = panels(shot)
    if found is None:
        return False
    s = found[1].astype(int)
    picture = s.min(axis=2) < 235  # not the panels' white background
    grey = (s.max(axis=2) - s.min(axis=2)) < 20
    return bool(grey[picture].mean() > 0.4)


class Lines:
    """A child's stdout, line by line, with a timeout."""

    def __init__(self, process: subprocess.Popen[str]) -> None:
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=lambda: [self.lines.put(line) for line in process.stdout], daemon=True).start()  # type: ignore[union-attr]
        self.seen: list[str] = []

    def until(self, words: str, timeout: float) -> str:
        while True:
            try:
                line = self.lines.get(timeout=timeout)
            except queue.Empty:
                raise AssertionError(f"no line with {words!r} within {timeout} s; got {self.seen}") from None
            self.seen.append(line)
            if words in line:
                return line


def agrisim(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "agrisim", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # Ctrl-C's default disposition, as from a terminal: a non-interactive shell's background
        # job passes SIGINT on ignored, and stop() would then wait in vain
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def stop(process: subprocess.Popen[str]) -> int:
    process.send_signal(signal.SIGINT)
    try:
        return process.wait(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()


def lowest_priority(process: subprocess.Popen[str]) -> None:
    """Every thread of ``process``'s children at the lowest priority (nice 19). The Rerun server
    that ``agrisim view`` starts keeps a thread busy for as long as it serves a recording file
    (its gRPC server polls the file's channel in a loop that yields rather than waits,
    rerun-io/rerun#10944: a whole core, measured 0.7 to 1 s of CPU time a second); at the lowest
    priority that loop gets only the CPU time the browser and the suite's other tests leave. The
    server's real work is small (serving the viewer and the stream of a live run: 0.1 s)."""
    threads = []
    for task in Path(f"/proc/{process.pid}/task").iterdir():
        with contextlib.suppress(OSError):  # a kernel without children files: left as they are
            for child in (task / "children").read_text().split():
                threads += [int(thread.name) for thread in Path(f"/proc/{child}/task").iterdir()]
    for thread in threads:
        with contextlib.suppress(OSError):  # one that has ended since
            os.setpriority(os.PRIO_PROCESS, thread, 19)


def look(url: str, tmp_path: Path, name: str) -> tuple[np.ndarray, list[str]]:
    """The page once it shows its views, and the viewer's notices (what it logged as warnings
    and errors to the console)."""
    with Page(url) as page:
        shot = page.wait_for(shows_views, timeout=150)
        notices = [text for level, text in page.console_lines() if level in ("warning", "error")]
    Image.fromarray(shot).save(tmp_path / f"{name}.png")  # for a look when it fails
    return shot, notices


def check_page(shot: np.ndarray, notices: list[str], saved: Path) -> None:
    assert shows_views(shot), f"the page shows no 3D, camera and depth views: {saved}"
    assert shows_photographs(shot), f"the camera panels show a colour map over the photographs: {saved}"
    timeline_notices = [n for n in notices if TIMELINE_NOTICE.search(n)]
    assert not timeline_notices, timeline_notices


def test_view_serves_a_runs_recording_to_a_browser(tmp_path: Path, saved_runs) -> None:  # noqa: ANN001
    run_dir = saved_runs.get(output={"no_rrd": False})
    web, grpc = free_port(), free_port()
    process = agrisim("view", str(run_dir), "--web-port", str(web), "--grpc-port", str(grpc))
    try:
        line = Lines(process).until("serving", timeout=60)
        lowest_priority(process)
        url = line.split(" at ", 1)[1].split()[0]
        assert url.startswith(f"http://127.0.0.1:{web}/")
        assert listening_addresses(web) == listening_addresses(grpc) == {"127.0.0.1"}  # loopback only
        check_page(*look(url, tmp_path, "view"), tmp_path / "view.png")
    finally:
        code = stop(process)
    assert code == 0, process.stderr.read() if process.stderr else ""
    assert not listening_addresses(web) and not listening_addresses(grpc)  # the server is gone


def test_run_serve_web_streams_the_run_live(tmp_path: Path) -> None:
    out = tmp_path / "run"
    web, grpc = free_port(), free_port()
    process = agrisim(
        "run",
        "--physics",
        "kinematic",
        "--setpoints",
        "1x3",
        "--resolution",
        "320x180",
        "--shadow-samples",
        "0",
        "--out",
        str(out),
        "--serve-web",
        "--web-port",
        str(web),
        "--grpc-port",
        str(grpc),
    )
    try:
        lines = Lines(process)
        url = lines.until("watch the run in a browser", timeout=120).split(": ", 1)[1].strip()
        lines.until("the run is over", timeout=300)
        # everything the page shows came through the gRPC stream: the server reads no file
        check_page(*look(url, tmp_path, "serve_web"), tmp_path / "serve_web.png")
    finally:
        code = stop(process)
    assert code == 0, process.stderr.read() if process.stderr else ""
    assert '"status": "complete"' in (out / "run.json").read_text() and (out / "recording.rrd").is_file()


def test_bad_addresses_are_refused(tmp_path: Path, cli) -> None:  # noqa: ANN001
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        rrd = tmp_path / "x.rrd"
        rrd.write_bytes(b"")
        for args, words in (
            (["view", str(rrd), "--web-port", str(port)], "cannot be used"),
            (["view", str(rrd), "--bind", "localhost:80"], "not an IP address"),
            (["view", str(rrd), "--web-port", "70000"], "not a port"),
            (["view", str(tmp_path)], "holds no recording.rrd"),
            (["run", "--web-port", "9000"], "go with --serve-web"),
            (["run", "--serve-web", "--grpc-port", str(port), "--out", str(tmp_path / "r")], "cannot be used"),
        ):
            code, _, err = cli(args)
            assert code == 2 and words in err and len(err.strip().splitlines()) == 1, (args, err)
    assert not (tmp_path / "r").exists()
