"""Counters for ``bench/suite_profile.py``, loaded by every Python process the profiled suite
starts (this folder is put first on ``PYTHONPATH``): pytest's workers, the ``agrisim`` commands
tests run, Ray's workers. Each process appends what it built to ``$SUITE_PROFILE_DIR/<pid>.jsonl``,
one JSON object a line, tagged with the test that was running (``$SUITE_PROFILE_TEST``, which the
pytest plugin sets before each phase and children inherit):

- ``ray``: a Ray cluster started (``ray.init``), with its seconds;
- ``kernels``: Dr.Jit kernels compiled from scratch, loaded from its disk cache, and the
  compilers' seconds (Dr.Jit's kernel history, drained after each phase and at exit);
- ``plant``: a plant grown (procedural or Helios), with its seconds;
- ``run``: an episode run (``Episode.run``), with its seconds;
- ``plan``: an OMPL motion plan, with its seconds and whether it failed (a failure spends the
  whole time budget: attempts x time);
- ``process``: a program started (``subprocess.Popen``): ``browser``, ``agrisim``, ``colmap`` or
  ``other``;
- ``cpu``: the CPU seconds (user and system) a child process used, recorded at its exit (pytest's
  workers record theirs per phase instead, in the plugin).

Nothing here changes what a test computes; the modules are wrapped as they are imported.
"""

from __future__ import annotations

import atexit
import functools
import importlib.abc
import importlib.machinery
import json
import os
import subprocess
import sys
import time
from typing import Any

_DIR = os.environ.get("SUITE_PROFILE_DIR")
TEST_ENV = "SUITE_PROFILE_TEST"


def record(kind: str, **fields: Any) -> None:
    """Append one event of this process to the profile."""
    if not _DIR:
        return
    event = {"kind": kind, "test": os.environ.get(TEST_ENV, ""), "pid": os.getpid(), **fields}
    try:
        with open(os.path.join(_DIR, f"{os.getpid()}.jsonl"), "a") as f:
            f.write(json.dumps(event) + "\n")
    except OSError:
        pass


def _timed(kind: str, fn: Any, detail: Any = None) -> Any:
    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            what = detail(*args, **kwargs) if detail else ""
            record(kind, secs=time.perf_counter() - start, detail=what)

    return wrapper


def drain_kernels() -> None:
    """Record the Dr.Jit kernels launched since the last drain: compiled, from disk, seconds."""
    dr = sys.modules.get("drjit")
    if dr is None or not hasattr(dr, "kernel_history"):
        return
    try:
        dr.kernel_history([dr.KernelType.JIT])  # (recorded by the wrapper below)
    except Exception:  # a Dr.Jit that is shutting down
        return


def _record_kernels(history: list) -> None:
    """Record the JIT kernels in a drained ``history``: compiled, from disk, seconds."""
    jit = sys.modules["drjit"].KernelType.JIT
    history = [k for k in history if k.get("type") == jit]
    fresh = sum(1 for k in history if not k.get("cache_hit") and not k.get("cache_disk"))
    disk = sum(1 for k in history if k.get("cache_disk"))  # (Dr.Jit counts those as hits too)
    backend = sum(float(k.get("backend_time", 0.0)) for k in history) / 1000.0
    if fresh or disk:
        record("kernels", compiled=fresh, from_disk=disk, secs=backend, launches=len(history))


def _patch_ray(mod: Any) -> None:
    mod.init = _timed("ray", mod.init)


def _patch_drjit(mod: Any) -> None:
    try:
        mod.set_flag(mod.JitFlag.KernelHistory, True)
    except Exception:
        pass
    drain = mod.kernel_history

    @functools.wraps(drain)
    def kernel_history(*args: Any, **kwargs: Any) -> Any:
        """Dr.Jit's history, recorded whoever drains it (tests that read it count too)."""
        history = drain(*args, **kwargs)
        _record_kernels(history)
        return history

    mod.kernel_history = kernel_history


def _patch_grow(mod: Any) -> None:
    if hasattr(mod, "grow"):
        mod.grow = _timed(
            "plant", mod.grow, lambda name, seed, *a, **k: f"{mod.__name__.rsplit('.', 1)[-1]}:{name}:{seed}"
        )


def _patch_ompl(mod: Any) -> None:
    plan = mod.OmplPlanner.plan

    @functools.wraps(plan)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start, failed = time.perf_counter(), True
        try:
            out = plan(*args, **kwargs)
            failed = False
            return out
        finally:
            record("plan", secs=time.perf_counter() - start, detail="failed" if failed else "ok")

    mod.OmplPlanner.plan = wrapper


def _patch_episode(mod: Any) -> None:
    mod.Episode.run = _timed("run", mod.Episode.run)


_PATCHES = {
    "ray": _patch_ray,
    "drjit": _patch_drjit,
    "agrisim.plugins.plants.procedural": _patch_grow,
    "agrisim.plugins.plants.helios": _patch_grow,
    "agrisim.episode": _patch_episode,
    "agrisim.plugins.planners.ompl_planner.backend": _patch_ompl,
}


class _Loader(importlib.abc.Loader):
    def __init__(self, inner: importlib.abc.Loader, patch: Any) -> None:
        self.inner, self.patch = inner, patch

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> Any:
        return self.inner.create_module(spec)

    def exec_module(self, module: Any) -> None:
        self.inner.exec_module(module)
        self.patch(module)


class _Finder(importlib.abc.MetaPathFinder):
    """Wraps the loader of the modules in ``_PATCHES`` so that they are patched once loaded."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        patch = _PATCHES.get(name)
        if patch is None:
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is not None and spec.loader is not None:
                spec.loader = _Loader(spec.loader, patch)
                return spec
        return None


def _program(args: Any) -> str:
    argv = [args] if isinstance(args, (str, bytes)) else list(args)
    words = " ".join(os.path.basename(str(a)) for a in argv[:3]).lower()
    for name in ("chrom", "colmap", "agrisim", "roscore", "rosmaster"):
        if name in words:
            return {"chrom": "browser", "rosmaster": "roscore"}.get(name, name)
    return "other"


_popen_init = subprocess.Popen.__init__


def _popen(self: Any, args: Any, *rest: Any, **kwargs: Any) -> None:
    record("process", detail=_program(args))
    _popen_init(self, args, *rest, **kwargs)


def _record_cpu() -> None:
    if "xdist" in sys.modules or "_pytest" in sys.modules:
        return  # a pytest process: the plugin counts its CPU phase by phase
    record("cpu", secs=time.process_time())


if _DIR:
    sys.meta_path.insert(0, _Finder())
    subprocess.Popen.__init__ = _popen  # type: ignore[method-assign]
    atexit.register(drain_kernels)
    atexit.register(_record_cpu)
