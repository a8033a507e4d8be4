"""Silencing native libraries that print to the process's stdout/stderr file descriptors.

pybullet prints its build time and ``argv[0]=`` on connect, OMPL logs every plan, nanobind
reports leaks at exit: none of it is for agrisim's user. Python-level redirection does not
catch C writes, so this works on the file descriptors themselves.
"""

from __future__ import annotations

import atexit
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def native_output_silenced(stdout: bool = True, stderr: bool = True) -> Iterator[None]:
    """Discard whatever native code writes to fd 1 / fd 2 inside the block."""
    fds = [fd for fd, on in ((1, stdout), (2, stderr)) if on]
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError):
            pass
    saved = []
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
    except OSError:  # no /dev/null: keep the output rather than fail
        yield
        return
    try:
        for fd in fds:
            try:
                saved.append((fd, os.dup(fd)))
                os.dup2(devnull, fd)
            except OSError:
                continue
        yield
    finally:
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


_exit_silenced = False


def silence_native_output_at_exit() -> None:
    """At interpreter exit, after everything agrisim printed, discard native stderr noise
    (nanobind's leak report from OMPL's bindings)."""
    global _exit_silenced
    if _exit_silenced:
        return
    _exit_silenced = True

    def _silence() -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (AttributeError, ValueError):
                pass
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 2)
        except OSError:
            pass

    atexit.register(_silence)
