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
from functools import lru_cache

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
