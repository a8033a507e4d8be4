"""agrisim's cache across processes (``$AGRISIM_CACHE_DIR``, else ``$XDG_CACHE_HOME/agrisim`` or
``~/.cache/agrisim``): results that are slow to make and never change for the same inputs, such
as converted robot meshes and the plants' leaf optics. Best effort: a cache that cannot be
written only costs the work again."""

from __future__ import annotations

import logging
import os
import pickle
import tempfile
from pathlib import Path

log = logging.getLogger(__name__)


def cache_dir(part: str) -> Path:
    """The folder of one kind of cached result, ``part``."""
    base = os.environ.get("AGRISIM_CACHE_DIR")
    if base:
        return Path(base).expanduser() / part
    xdg = os.environ.get("XDG_CACHE_HOME")
    root = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return root / "agrisim" / part


def write_cached(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all (a temp file renamed: a concurrent run
    never reads half an entry); a cache that cannot be written is logged, not raised."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)  # mkstemp makes it private; the cache is shared by users' runs
        os.replace(tmp, path)
    except OSError as exc:
        log.debug("cache %s not written: %s", path, exc)


def read_pickle(path: Path) -> object | None:
    """The object kept at ``path`` by :func:`write_pickle`, or None: none kept, or an entry that
    cannot be read (truncated, made by other versions), which the caller then makes again."""
    try:
        return pickle.loads(path.read_bytes())
    except FileNotFoundError:
        return None
    except Exception as exc:  # noqa: BLE001 - any unreadable entry is a miss
        log.debug("cache %s unreadable: %s", path, exc)
        return None


def write_pickle(path: Path, value: object) -> None:
    """Keep ``value`` at ``path`` (see :func:`write_cached`)."""
    write_cached(path, pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL))
