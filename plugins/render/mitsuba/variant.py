"""Which Mitsuba variant runs here: CUDA when an NVIDIA GPU is usable, else LLVM on the CPU.

Mitsuba's variant is process-wide (``mitsuba.set_variant``); every renderer of a process uses the
one chosen first. Dr.Jit's LLVM backend loads a shared libLLVM at run time: version 15 or newer
(on Debian, ``libllvm19``; ``DRJIT_LIBLLVM_PATH`` names a file), and CUDA needs the NVIDIA driver.
``AGRISIM_LLVM_TARGET=avx2`` makes that backend compile for AVX2 on an AVX-512 machine, as it
would on an AVX2 one (:func:`agrisim.plugins.render.mitsuba.cpu.emulate_llvm_target`; the test suite's
``AGRISIM_TEST_CPU`` sets it).
"""

from __future__ import annotations

import os
import re
import subprocess
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from typing import Any

from agrisim.errors import ConfigError

#: short names of the options -> Mitsuba's RGB variants
VARIANTS = {"cuda": "cuda_ad_rgb", "llvm": "llvm_ad_rgb"}

LLVM_HELP = (
    "the CPU variant needs a shared libLLVM 15 or newer (Debian/Ubuntu: apt-get install libllvm19, which "
    "scripts/setup.sh does; or set DRJIT_LIBLLVM_PATH to the library)"
)


_LIBLLVM = re.compile(r"libLLVM(?:-(\d+)[.\d]*\.so|\.so\.(\d+))[.\d]*\s.*=>\s*(\S+)")


def newest_libllvm(listing: str) -> str | None:
    """The newest libLLVM of version 16 or more in ``ldconfig -p`` output, or None."""
    found = []
    for line in listing.splitlines():
        m = _LIBLLVM.search(line)
        if m:
            version = int(m.group(1) or m.group(2))
            if version >= 16:
                found.append((version, m.group(3)))
    return max(found)[1] if found else None


def _point_drjit_at_libllvm() -> None:
    """Name the newest libLLVM 16+ in ``DRJIT_LIBLLVM_PATH`` unless the user set it: Dr.Jit
    would otherwise take the first it finds, and LLVM 15 (accepted) aborts on some kernels."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return
    try:
        listing = subprocess.run(["ldconfig", "-p"], capture_output=True, text=True, timeout=10).stdout
    except (OSError, subprocess.SubprocessError):
        return
    path = newest_libllvm(listing)
    if path:
        os.environ["DRJIT_LIBLLVM_PATH"] = path


@lru_cache(maxsize=1)
def _backends() -> tuple[bool, bool]:
    """(CUDA usable, LLVM usable), asked once: Dr.Jit probes its backends on import."""
    _point_drjit_at_libllvm()
    try:
        import drjit as dr
    except ImportError as exc:
        raise ConfigError(f"renderer 'mitsuba' needs the packages mitsuba and drjit ({exc})") from None
    cuda, llvm = bool(dr.has_backend(dr.JitBackend.CUDA)), bool(dr.has_backend(dr.JitBackend.LLVM))
    if llvm:
        # here, before the first kernel of any renderer: the target applies to later kernels only
        from agrisim.plugins.render.mitsuba.cpu import LLVM_TARGET_ENV, emulate_from_environment

        try:
            emulate_from_environment()
        except (ValueError, RuntimeError) as exc:
            raise ConfigError(f"${LLVM_TARGET_ENV}: {exc}") from None
    return cuda, llvm


def resolve_variant(choice: str, renderer: str = "mitsuba") -> str:
    """The Mitsuba variant for ``choice`` (``auto``, ``cuda`` or ``llvm``), or a ConfigError
    saying what is missing (naming the options of ``renderer``, whose choice it is)."""
    if choice not in ("auto", *VARIANTS):
        raise ConfigError(f"[renderer.{renderer}] variant {choice!r} is unknown; allowed: auto, cuda, llvm")
    cuda, llvm = _backends()
    if choice == "cuda" and not cuda:
        raise ConfigError(
            f"[renderer.{renderer}] variant 'cuda' needs a usable NVIDIA GPU and driver; none found "
            "(use variant = 'llvm' or 'auto' for the CPU)"
        )
    if choice == "llvm" and not llvm:
        raise ConfigError(f"[renderer.{renderer}] variant 'llvm': Dr.Jit found no usable libLLVM; {LLVM_HELP}")
    if choice == "auto":
        if cuda:
            return VARIANTS["cuda"]
        if not llvm:
            raise ConfigError(f"renderer {renderer!r}: no NVIDIA GPU and no usable libLLVM; {LLVM_HELP}")
        return VARIANTS["llvm"]
    return VARIANTS[choice]


def use_variant(choice: str, renderer: str = "mitsuba"):  # noqa: ANN201 - the mitsuba module (typed lazily)
    """Mitsuba set to the variant for ``choice`` (the first one set in a process stays: Mitsuba's
    variant is global, and switching it would invalidate scenes already loaded)."""
    import mitsuba as mi

    variant = resolve_variant(choice, renderer)
    current = mi.variant()
    if current is None:
        mi.set_variant(variant)
    elif current != variant:
        raise ConfigError(
            f"renderer {renderer!r}: this process already renders with {current}; {variant} cannot join it "
            "(one Mitsuba variant per process)"
        )
    return mi


class GeometryVariant:
    """Mitsuba's ``*_mono`` variant on the backend of the process's own (RGB) variant, as a
    module-like object, for an exact pass that lives beside a path tracer.

    Why: Dr.Jit traces a virtual call over every instance alive in the variant's registry, and a
    path tracer's calls on shapes nest (each instance's shape group dispatches again over every
    shape alive). The exact pass's arm links, a shape group and an instance each, made in the
    path tracer's variant made each of its views' tracing several times dearer on a CPU (0.5 ->
    1.9 s a view at 48x36, two UR10s) and its kernel a third larger. In another variant they
    live in another registry; the arrays are Dr.Jit's own types, the same in both, so what the
    exact pass computes does not change.

    Mitsuba builds plugins in the process's current variant only, and switching it reloads its
    Python modules (0.2 s a switch): everything the exact pass makes from dictionaries is made
    inside :meth:`building` (one switch there and one back); afterwards ``load_dict`` takes only
    a scene of shapes already made, built from its class.
    """

    def __init__(self, mi: Any) -> None:
        import mitsuba

        self._mitsuba = mitsuba
        self._variant = mi.variant().replace("_rgb", "_mono")
        self._module = getattr(mitsuba, self._variant)
        self._building = False

    def variant(self) -> str:
        return self._variant

    @contextmanager
    def building(self) -> Iterator[None]:
        """Make this variant Mitsuba's current one meanwhile (in this thread and every other)."""
        with warnings.catch_warnings(), self._mitsuba.scoped_set_variant(self._variant):
            # each switch re-imports Mitsuba's integrators, whose @dr.syntax functions then count
            # as transformed again: past 1000, Dr.Jit would warn of a loop that is not there
            warnings.filterwarnings("ignore", "The AST-transforming decorator", RuntimeWarning)
            self._building = True
            try:
                yield
            finally:
                self._building = False

    def load_dict(self, d: dict[str, Any]) -> Any:
        if self._building:
            return self._mitsuba.load_dict(d)
        if d.get("type") != "scene" or any(isinstance(v, dict) for v in d.values()):
            raise RuntimeError(f"{self._variant}: only a scene of shapes already made is built outside building()")
        props = self._mitsuba.Properties("scene")
        for key, value in d.items():
            if key != "type":
                props[key] = value
        return self._module.Scene(props)

    def traverse(self, node: Any) -> Any:
        if not self._building:
            raise RuntimeError(f"{self._variant}: traverse() only inside building()")
        return self._mitsuba.traverse(node)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._module, name)
