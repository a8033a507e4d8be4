"""Atomic file writes: a reader sees the old file or the new one, never half of one."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _current_umask()


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same directory + rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes files private; results are not
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def write_through(path: Path, writer: Callable[[str], bool]) -> None:
    """Atomically write ``path`` with a library's writer that takes a file name and says whether
    it succeeded (Open3D's). The temporary file keeps ``path``'s suffix, because such writers
    pick the format by extension."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    try:
        if not writer(tmp):
            raise OSError(f"could not write {path}")
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def is_partial(path: Path) -> bool:
    """Is ``path`` the temporary file of a write that never finished (the process was killed)?"""
    name = Path(path).name
    return name.startswith(".") and ".tmp" in name


def remove_partial(root: Path) -> int:
    """Delete temporary files of unfinished writes under ``root``; returns how many."""
    count = 0
    for path in Path(root).rglob(".*"):
        if path.is_file() and is_partial(path):
            path.unlink(missing_ok=True)
            count += 1
    return count


def write_json(path: Path, obj: Any, compact: bool = False) -> None:
    """Pretty JSON (``compact``: without spaces or line breaks, for long number arrays),
    written atomically."""
    text = (
        json.dumps(obj, separators=(",", ":"), default=to_json)
        if compact
        else json.dumps(obj, indent=2, default=to_json)
    )
    write_bytes(path, (text + "\n").encode())


def to_json(obj: Any) -> Any:
    """What JSON holds for numpy scalars and arrays and for paths (``json.dumps``' ``default``)."""
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot serialise {type(obj).__name__}")


@contextmanager
def staged_dir(out: Path) -> Iterator[Path]:
    """A folder to fill in place of the folder ``out``: a hidden sibling that becomes ``out`` (an
    existing ``out`` replaced) only when the block ends without an error; otherwise it is
    removed and ``out`` stays as it was."""
    out = Path(out)
    staging = out.parent / f".{out.name}.{os.getpid()}.tmp"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        yield staging
        if out.exists():
            trash = out.parent / f".{out.name}.{os.getpid()}.old.tmp"
            os.replace(out, trash)
            os.replace(staging, out)
            shutil.rmtree(trash)
        else:
            os.replace(staging, out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
