"""A real headless browser for the tests: Debian's ``chromium-headless-shell`` (or
``chromium``), driven over the DevTools protocol through a pipe (``--remote-debugging-pipe``:
JSON messages separated by NUL bytes on file descriptors 3 and 4), so no WebDriver or websocket
library is needed. WebGL runs on SwiftShader, Chromium's CPU rasterizer. The page's console is
kept (``Page.console_lines()``), so a test can read what the page logged, e.g. a viewer's notices.

One browser per test process (an xdist worker): the first page starts it, the pages that follow
share it, each in a browser context of its own (an incognito profile: no cookie, storage or cache
passes from one page to the next), and it is closed when the process exits (or when its pipe
closes, should the process be killed). Starting Chromium is cheap (0.3 s); what sharing saves is
mostly the GPU process's work on the WebGL shaders, which SwiftShader compiles on the CPU: a
second page of the Rerun viewer in the same browser took 22 s of CPU time where the first took
28 s (medians of three)."""

from __future__ import annotations

import atexit
import base64
import contextlib
import io
import json
import os
import shutil
import subprocess
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from PIL import Image

BROWSERS = ("chromium-headless-shell", "chromium")


def browser() -> str | None:
    """The headless browser's executable, or None."""
    return next((path for name in BROWSERS if (path := shutil.which(name))), None)


class Browser:
    """One headless Chromium process and its DevTools pipe; pages are its targets."""

    def __init__(self) -> None:
        exe = browser()
        if exe is None:
            raise RuntimeError(f"no headless browser: install Debian's {BROWSERS[0]}")
        self._from_browser, to_us = os.pipe()
        from_us, self._to_browser = os.pipe()

        def descriptors() -> None:  # the browser reads commands on 3 and answers on 4
            os.dup2(from_us, 3)
            os.dup2(to_us, 4)

        self.process = subprocess.Popen(
            [
                exe,
                "--headless",
                "--no-sandbox",
                "--remote-debugging-pipe",
                "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader",
                # WebGL still draws on SwiftShader, but the page is composited by Skia on the CPU
                # rather than through SwiftShader too: the Rerun viewer's panels come out pixel
                # for pixel the same, for about a fifth less CPU time a page
                "--disable-gpu-compositing",
                "--window-size=1600,900",  # each page sets its own size
                "about:blank",
            ],
            pass_fds=(3, 4),  # kept open once preexec_fn has put the pipes there
            preexec_fn=descriptors,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(from_us)
        os.close(to_us)
        self._buffer = b""
        self._id = 0
        #: the open pages by DevTools session, which the console events name
        self._pages: dict[str, Page] = {}

    def alive(self) -> bool:
        return self.process.poll() is None and self._to_browser >= 0

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> dict[str, Any]:
        """Send one command (to a page's ``session``, or to the browser) and return its result;
        console events that arrive meanwhile go to their pages."""
        self._id += 1
        message: dict[str, Any] = {"id": self._id, "method": method, "params": params or {}}
        if session is not None:
            message["sessionId"] = session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        while True:
            while b"\0" not in self._buffer:
                chunk = os.read(self._from_browser, 1 << 20)
                if not chunk:
                    raise RuntimeError("the browser closed its DevTools pipe")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]
            if reply.get("method") == "Runtime.consoleAPICalled" and (page := self._pages.get(reply.get("sessionId"))):
                event = reply["params"]
                text = " ".join(str(arg.get("value", arg.get("description", ""))) for arg in event["args"])
                page.console.append((event["type"], text))

    def close(self) -> None:
        if self._to_browser < 0:
            return
        self.process.kill()
        self.process.wait()
        os.close(self._from_browser)
        os.close(self._to_browser)
        self._from_browser = self._to_browser = -1


_shared: Browser | None = None


def _close_shared() -> None:
    if _shared is not None:
        _shared.close()


atexit.register(_close_shared)


def shared_browser() -> Browser:
    """This process's browser, started on first use (and again if it has died)."""
    global _shared
    if _shared is None or not _shared.alive():
        if _shared is not None:
            _shared.close()
        _shared = Browser()
    return _shared


class Page:
    """One browser tab at ``url``, sized ``width`` x ``height``, in a browser context of its own
    of this process's browser."""

    def __init__(self, url: str, width: int = 1600, height: int = 900) -> None:
        self.browser = shared_browser()
        #: the browser's process (shared with this process's other pages)
        self.process = self.browser.process
        #: what the page logged to its console, in order: (level, text), level as the console
        #: call's name ("log", "debug", "info", "warning", "error", ...)
        self.console: list[tuple[str, str]] = []
        self.context = self.browser.call("Target.createBrowserContext")["browserContextId"]
        self.target = ""
        try:
            self.target = self.browser.call(
                "Target.createTarget",
                {"url": url, "width": width, "height": height, "browserContextId": self.context},
            )["targetId"]
            self.session = self.browser.call("Target.attachToTarget", {"targetId": self.target, "flatten": True})[
                "sessionId"
            ]
            self.browser._pages[self.session] = self
            # the lines logged before this are not lost: enabling replays those the page has kept
            self.call("Runtime.enable", session=self.session)
            # without the stack trace of each line, which this class does not keep: V8 walks the
            # stack, and the browser forwards the trace, for every console call (the Rerun
            # viewer logs 25,000 debug lines as it starts: 14 s of CPU time a page with them)
            with contextlib.suppress(RuntimeError):  # (experimental: a browser without it is slower)
                self.call("Runtime.setMaxCallStackSizeToCapture", {"size": 0}, self.session)
            # focused as the page a reader types into would be: a headless tab in the background
            # may not be, and then focus() and typed text go nowhere (the docs' search box)
            self.call("Emulation.setFocusEmulationEnabled", {"enabled": True}, self.session)
        except BaseException:
            self.close()
            raise

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> dict[str, Any]:
        return self.browser.call(method, params, session)

    def console_lines(self) -> list[tuple[str, str]]:
        """Everything the page has logged to its console so far (events are read while waiting
        for replies, so one round trip first takes in those still in the pipe)."""
        self.call("Runtime.evaluate", {"expression": "0"}, self.session)
        return list(self.console)

    def screenshot(self) -> np.ndarray:
        """The tab as an RGB array. (``optimizeForSpeed``: a quicker PNG encoding, larger but
        lossless: the same pixels for a fifth of the browser's time.)"""
        params = {"format": "png", "optimizeForSpeed": True}
        data = self.call("Page.captureScreenshot", params, self.session)["data"]
        return np.asarray(Image.open(io.BytesIO(base64.b64decode(data))).convert("RGB"))

    def wait_for(self, ready: Callable[[np.ndarray], bool], timeout: float, every: float = 3.0) -> np.ndarray:
        """Screenshots until ``ready`` holds for one (returned) or ``timeout`` seconds pass
        (the last one is returned)."""
        deadline = time.monotonic() + timeout
        while True:
            shot = self.screenshot()
            if ready(shot) or time.monotonic() > deadline:
                return shot
            time.sleep(every)

    def close(self) -> None:
        """Close the tab and its context (the browser stays, for the next page)."""
        self.browser._pages.pop(getattr(self, "session", ""), None)
        if not self.browser.alive():
            return
        try:
            if self.target:
                self.browser.call("Target.closeTarget", {"targetId": self.target})
            self.browser.call("Target.disposeBrowserContext", {"browserContextId": self.context})
        except RuntimeError:  # a browser that no longer answers: the next page starts another
            self.browser.close()

    def __enter__(self) -> Page:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
