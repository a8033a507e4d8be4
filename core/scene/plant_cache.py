"""Grown plants kept on disk, opt-in (``AGRISIM_PLANT_CACHE=DIR``): a species grown once from a
seed and options is read back by every later run that asks for the same, in this process or
another (a sweep's Ray workers, ``agrisim compare``'s two modes of one plant, a test session's
workers). Growing is deterministic, so a kept plant is the plant the species would grow again;
what it does not know is a change to the species' code, so a cache folder belongs to one
checkout and version (the test suite makes a fresh one a session). Off by default."""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Callable
from pathlib import Path

from pydantic import BaseModel

from agrisim.scene.model import Plant
from agrisim.util.cache import read_pickle, write_pickle
from agrisim.version import __version__

#: the environment variable naming the cache's folder; unset or empty: no cache
PLANT_CACHE_ENV = "AGRISIM_PLANT_CACHE"


def plant_cache_dir() -> Path | None:
    """The folder of kept plants, or None when the cache is off."""
    folder = os.environ.get(PLANT_CACHE_ENV, "").strip()
    return Path(folder).expanduser() if folder else None


def cache_path(folder: Path, species: str, options: BaseModel, seed: int) -> Path:
    """Where the plant ``species`` grown from ``seed`` with ``options`` is kept."""
    what = json.dumps([species, type(options).__qualname__, options.model_dump(mode="json"), seed, __version__])
    digest = hashlib.sha256(what.encode()).hexdigest()[:20]
    return folder / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', species)}-{seed}-{digest}.pickle"


def grown(species: str, options: BaseModel, seed: int, grow: Callable[[int], Plant]) -> Plant:
    """``grow(seed)``, or the plant kept from an earlier identical call when the cache is on
    (a fresh copy each time: callers may change what they get). An unreadable entry is grown
    again; one that cannot be written costs only the next call's growing."""
    folder = plant_cache_dir()
    if folder is None:
        return grow(seed)
    path = cache_path(folder, species, options, seed)
    kept = read_pickle(path)
    if isinstance(kept, Plant):
        return kept
    plant = grow(seed)
    write_pickle(path, plant)
    return plant
