"""Watching a run in a browser: the web viewer bundled with the Rerun SDK, served by its own
``rerun --serve-web`` (the SDK's command line) in a child process.

The server is bound to loopback unless another address is asked for (``--bind``): a recording
shows the whole lab and the run's configuration, and the viewer has no authentication. For a
remote headless machine, forward the two ports over SSH (``ssh -L 9090:localhost:9090 -L
9876:localhost:9876 HOST``) rather than binding every interface.
"""

from __future__ import annotations

import argparse
import ipaddress
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

from agrisim.errors import UserError

#: Rerun's own defaults: the web page and the gRPC server it reads the recording from
DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876
DEFAULT_BIND = "127.0.0.1"


def check_address(bind: str, ports: dict[str, int]) -> None:
    """Refuse an address that is not an IP of this machine, a port outside 1..65535 or one
    already in use, naming the flag."""
    try:
        ip = ipaddress.ip_address(bind)
    except ValueError:
        raise UserError(
            f"--bind {bind!r} is not an IP address (127.0.0.1 for this machine only, 0.0.0.0 for every interface)"
        ) from None
    for flag, port in ports.items():
        if not 1 <= port <= 65535:
            raise UserError(f"{flag} {port} is not a port number (1..65535)")
        with socket.socket(socket.AF_INET6 if ip.version == 6 else socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind((bind, port))
            except OSError as exc:
                raise UserError(
                    f"{flag} {port} on {bind} cannot be used ({exc.strerror}); choose another port"
                ) from None


def _accepting(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.5):
            return True
    except OSError:
        return False


@dataclass
class WebViewer:
    """A running ``rerun --serve-web``: ``url`` is the page to open, ``grpc_url`` where
    loggers send data (``[sink.rerun] connect``)."""

    process: subprocess.Popen[bytes]
    url: str
    grpc_url: str
    log: Path
    _tmp: tempfile.TemporaryDirectory[str] = field(repr=False)

    def wait(self) -> int:
        """Serve until the server exits, Ctrl-C or SIGTERM (then stop it); returns its exit
        status, 0 when stopped."""

        def interrupt(signum: int, frame: object) -> None:
            raise KeyboardInterrupt

        previous = signal.signal(signal.SIGTERM, interrupt)
        try:
            return self.process.wait()
        except KeyboardInterrupt:
            self.stop()
            return 0
        finally:
            signal.signal(signal.SIGTERM, previous)

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._tmp.cleanup()

    def __enter__(self) -> WebViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def rerun_executable() -> str:
    """The ``rerun`` binary the SDK's wheel ships (``python -m rerun`` would run it as a
    grandchild, which stopping the child would leave behind)."""
    import importlib.util

    spec = importlib.util.find_spec("rerun_cli")
    if spec is None or not spec.submodule_search_locations:
        raise UserError("the Rerun SDK's command line (rerun_cli, part of rerun-sdk) is not installed")
    exe = Path(next(iter(spec.submodule_search_locations))) / (
        "rerun.exe" if sys.platform.startswith("win") else "rerun"
    )
    if not exe.is_file():
        raise UserError(f"the Rerun SDK's viewer binary is missing ({exe}); reinstall rerun-sdk")
    return str(exe)


def _host(bind: str) -> str:
    """The host name a browser uses to reach a server bound to ``bind``."""
    host = socket.gethostname() if ipaddress.ip_address(bind).is_unspecified else bind
    return f"[{host}]" if ":" in host else host


def grpc_url(bind: str, grpc_port: int) -> str:
    """Where loggers and the web page reach the gRPC server of a viewer served on ``bind``."""
    return f"rerun+http://{_host(bind)}:{grpc_port}/proxy"


def serve_web(
    recording: Path | None = None,
    bind: str = DEFAULT_BIND,
    web_port: int = DEFAULT_WEB_PORT,
    grpc_port: int = DEFAULT_GRPC_PORT,
    timeout: float = 60.0,
) -> WebViewer:
    """Start the web viewer, serving ``recording`` (an .rrd file) or, without one, whatever a
    logger streams to ``grpc_url``; returns once both ports accept connections."""
    check_address(bind, {"--web-port": web_port, "--grpc-port": grpc_port})
    url = grpc_url(bind, grpc_port)
    tmp = tempfile.TemporaryDirectory(prefix="agrisim-web-")
    log = Path(tmp.name) / "rerun.log"
    args = [
        rerun_executable(),
        "--serve-web",
        "--bind",
        bind,
        "--port",
        str(grpc_port),
        "--web-viewer-port",
        str(web_port),
    ]
    if recording is not None:
        args.append(str(recording))
    with open(log, "wb") as out:
        process = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
    viewer = WebViewer(process, f"http://{_host(bind)}:{web_port}/?url={quote(url, safe='')}", url, log, tmp)
    probe = "127.0.0.1" if ipaddress.ip_address(bind).is_unspecified else bind
    deadline = time.monotonic() + timeout
    while not (_accepting(probe, web_port) and _accepting(probe, grpc_port)):
        if process.poll() is not None or time.monotonic() > deadline:
            lines = log.read_text(errors="replace").strip().splitlines()
            viewer.stop()
            raise RuntimeError(f"the Rerun web viewer did not start: {lines[-1] if lines else 'no output'}")
        time.sleep(0.1)
    return viewer


def recording_of(target: Path) -> Path:
    """The recording ``agrisim view`` serves: an .rrd file, or a run directory's own."""
    from agrisim.files import layout

    if target.is_file() and target.suffix == ".rrd":
        return target
    if target.is_dir():
        rrd = target / layout.RECORDING
        if rrd.is_file():
            return rrd
        raise UserError(
            f"{target} holds no {layout.RECORDING} (made with --no-rrd, or --rrd elsewhere: give that file)"
        )
    raise UserError(f"{target} is neither a run directory nor an .rrd recording")


def web_flags(parser: argparse.ArgumentParser) -> None:
    """``--web-port``, ``--grpc-port``, ``--bind``: where the web viewer serves."""
    parser.add_argument("--web-port", type=int, metavar="N", help=f"port of the web page (default: {DEFAULT_WEB_PORT})")
    parser.add_argument(
        "--grpc-port",
        type=int,
        metavar="N",
        help=f"port the page reads the recording from (default: {DEFAULT_GRPC_PORT})",
    )
    parser.add_argument(
        "--bind",
        metavar="ADDR",
        help=f"address to serve on (default: {DEFAULT_BIND}, this machine only; 0.0.0.0: every interface)",
    )


def web_address(args: argparse.Namespace) -> tuple[str, int, int]:
    """(bind, web port, gRPC port) of ``--bind``, ``--web-port``, ``--grpc-port``, checked."""
    bind = args.bind or DEFAULT_BIND
    web = args.web_port if args.web_port is not None else DEFAULT_WEB_PORT
    grpc = args.grpc_port if args.grpc_port is not None else DEFAULT_GRPC_PORT
    if web == grpc:
        raise UserError(f"--web-port and --grpc-port must differ (both {web})")
    check_address(bind, {"--web-port": web, "--grpc-port": grpc})
    return bind, web, grpc
