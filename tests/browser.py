"""A real headless browser for the tests: Debian's ``chromium-headless-shell`` (or
``chromium``), driven over the DevTools protocol through a pipe (``--remote-debugging-pipe``:
JSON messages separated by NUL bytes on file descriptors 3 and 4), so no WebDriver or websocket
library is needed. WebGL runs on SwiftShader, Chromium's CPU rasterizer. The page's console is
kept (``Page.console_lines()``), so a test can read what the page logged, e.g. a viewer's notices."""

from __future__ import annotations

import base64
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


class Page:
    """One browser tab at ``url``, sized ``width`` x ``height``."""

    def __init__(self, url: str, width: int = 1600, height: int = 900) -> None:
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
                f"--window-size={width},{height}",
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
        #: what the page logged to its console, in order: (level, text), level as the console
        #: call's name ("log", "debug", "info", "warning", "error", ...)
        self.console: list[tuple[str, str]] = []
        target = self.call("Target.createTarget", {"url": url, "width": width, "height": height})["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        # the lines logged before this are not lost: enabling replays those the page has kept
        self.call("Runtime.enable", session=self.session)

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> dict[str, Any]:
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
            if reply.get("method") == "Runtime.consoleAPICalled":
                event = reply["params"]
                text = " ".join(str(arg.get("value", arg.get("description", ""))) for arg in event["args"])
                self.console.append((event["type"], text))

    def console_lines(self) -> list[tuple[str, str]]:
        """Everything the page has logged to its console so far (events are read while waiting
        for replies, so one round trip first takes in those still in the pipe)."""
        self.call("Runtime.evaluate", {"expression": "0"}, self.session)
        return list(self.console)

    def screenshot(self) -> np.ndarray:
        """The tab as an RGB array."""
        data = self.call("Page.captureScreenshot", {"format": "png"}, self.session)["data"]
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
        self.process.kill()
        self.process.wait()
        os.close(self._from_browser)
        os.close(self._to_browser)

    def __enter__(self) -> Page:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
