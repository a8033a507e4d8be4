"""The host CPU, and Dr.Jit's CPU backend compiling as if for another one.

:func:`vector_isa` and :func:`cpu_model` say what this machine is (from ``/proc/cpuinfo``).

:func:`emulate_llvm_target` makes Dr.Jit's LLVM backend (on which the ``raycast`` and ``mitsuba``
renderers run on the CPU) generate code for another vector ISA than the host's: on an AVX-512
machine, ``emulate_llvm_target("avx2")`` compiles every later kernel 8 lanes wide with AVX2 and
FMA only, as Dr.Jit does on an AVX2 machine (AMD EPYC Zen 2/3, Intel before Skylake-X). The code
then picks the same instructions and intrinsics as there (``rsqrtps`` and its Newton step where
AVX-512 has ``vrsqrt14ps``, no ``zmm`` register), and its kernels get other keys in Dr.Jit's
disk cache (``~/.drjit``): the IR differs, so nothing compiled for the host's ISA is reused.

What it does not change (it cannot, from inside a process):

* Embree, inside Mitsuba, picks its kernels from CPUID (AVX-512 here). Dr.Jit calls it with
  packets of the vector width, so its 8-wide entry points are the ones used, as on AVX2.
* OpenBLAS (numpy, scipy) picks its kernels when it loads: ``OPENBLAS_CORETYPE=Haswell`` in
  the environment of the process forces its AVX2 ones.
* numpy picks its own SIMD loops when it loads too, and on AVX-512 its float64 ``exp``, ``log``,
  ``power``, ``arctan2``, ``arccos`` (and more) round differently in the last bit from its AVX2
  ones: ``NPY_DISABLE_CPU_FEATURES`` naming the targets beyond AVX2
  (:func:`numpy_wide_targets`) makes it take the AVX2 ones.
* The results of the approximate instructions (``rsqrtps``) are the host's silicon's: Intel's
  and AMD's differ in the last bits before the Newton step, so an emulated run is an AVX2
  machine's code on this machine's arithmetic, not an AMD EPYC's bit for bit.
"""

from __future__ import annotations

import ctypes
import importlib
import os
import platform
from functools import lru_cache
from pathlib import Path
from typing import NamedTuple

#: the environment variable through which a process asks for :func:`emulate_llvm_target`
#: (read where agrisim first sets Dr.Jit up: :mod:`agrisim.plugins.render.mitsuba.variant`)
LLVM_TARGET_ENV = "AGRISIM_LLVM_TARGET"


class LLVMTarget(NamedTuple):
    """What Dr.Jit's LLVM backend compiles for: LLVM's CPU name, its feature string (as LLVM
    writes it, ``+avx2,-avx512f,...``) and the number of lanes of a vector."""

    cpu: str
    features: str
    width: int


# x86-64-v3 (AVX2, FMA, BMI1/2, F16C, LZCNT, MOVBE): what every AVX2 machine has. The features
# are spelled out because Dr.Jit looks for "+avx" and "+avx512vl" in this string to choose its
# intrinsics, and LLVM takes it whole instead of the host's; AVX-512 is turned off explicitly.
_AVX2_FEATURES = ",".join(
    [
        *(f"+{f}" for f in ("64bit", "cmov", "cx8", "cx16", "fxsr", "mmx", "sahf", "popcnt", "xsave")),
        *(f"+{f}" for f in ("sse", "sse2", "sse3", "ssse3", "sse4.1", "sse4.2")),
        *(f"+{f}" for f in ("avx", "avx2", "fma", "f16c", "bmi", "bmi2", "lzcnt", "movbe")),
        *(f"-{f}" for f in ("avx512f", "avx512vl", "avx512bw", "avx512dq", "avx512cd", "evex512")),
    ]
)

#: the targets :func:`emulate_llvm_target` knows, by the ISA's name
TARGETS: dict[str, LLVMTarget] = {"avx2": LLVMTarget("x86-64-v3", _AVX2_FEATURES, 8)}


#: where Linux lists the processors and their flags
CPUINFO = Path("/proc/cpuinfo")


def cpuinfo(path: Path = CPUINFO) -> dict[str, str]:
    """The first processor's fields in ``path`` (Linux's ``/proc/cpuinfo``; empty where there is
    none): ``"model name"``, ``"flags"``..."""
    fields: dict[str, str] = {}
    try:
        text = Path(path).read_text()
    except OSError:
        return fields
    for line in text.splitlines():
        if not line.strip():
            if fields:
                break  # one processor is enough: they are alike
            continue
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    return fields


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), e.g. ``"AMD EPYC 7B13"``; else what
    :func:`platform.processor` says, else ``"unknown"``."""
    return cpuinfo().get("model name") or platform.processor() or "unknown"


def vector_isa(info: dict[str, str] | None = None) -> str:
    """The widest vector ISA of the host: ``"AVX-512"``, ``"AVX2"``, ``"AVX"``, ``"SSE4.2"``,
    ``"SSE2"`` (x86-64), ``"NEON"`` (ARM), or ``"unknown"`` (no ``/proc/cpuinfo``). AVX-512 is
    counted with AVX512VL, as Dr.Jit counts it (its 16-lane vectors need it); AVX2 with FMA.
    ``info``: :func:`cpuinfo`'s fields, read here if not given."""
    info = cpuinfo() if info is None else info
    flags = set((info.get("flags") or info.get("Features") or "").split())
    if not flags:
        return "unknown"
    for isa, needs in (
        ("AVX-512", {"avx512f", "avx512vl"}),
        ("AVX2", {"avx2", "fma"}),
        ("AVX", {"avx"}),
        ("SSE4.2", {"sse4_2"}),
        ("SSE2", {"sse2"}),
        ("NEON", {"asimd"}),
    ):
        if needs <= flags:
            return isa
    return "unknown"


def numpy_simd() -> tuple[list[str], list[str]]:
    """numpy's runtime SIMD dispatch: (the targets it was built to dispatch to, those this
    process uses), e.g. (["X86_V3", "X86_V4", "AVX512_ICL", "AVX512_SPR"], ["X86_V3"])."""
    try:  # numpy 2 (numpy 1 names the package numpy.core); untyped, so imported by name
        umath = importlib.import_module("numpy._core._multiarray_umath")
    except ImportError:
        umath = importlib.import_module("numpy.core._multiarray_umath")
    built, present = list(umath.__cpu_dispatch__), umath.__cpu_features__
    return built, [t for t in built if present.get(t)]


def numpy_wide_targets() -> list[str]:
    """numpy's dispatch targets beyond AVX2 (AVX-512's), in use or not: what
    ``NPY_DISABLE_CPU_FEATURES`` names to make numpy compute as on an AVX2 machine."""
    built, _ = numpy_simd()
    return [t for t in built if t == "X86_V4" or t.startswith("AVX512")]


def openblas_cores() -> dict[str, str]:
    """The OpenBLAS libraries loaded in this process (file name -> the core whose kernels it
    runs, e.g. ``"SkylakeX"``, ``"Haswell"``, ``"Zen"``): numpy's and scipy's each bundle one.
    OpenBLAS picks the core from CPUID when it loads, or from ``$OPENBLAS_CORETYPE``."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return {}
    paths = sorted({line.split()[-1] for line in maps.splitlines() if "openblas" in line and "/" in line})
    cores: dict[str, str] = {}
    for path in paths:
        try:
            lib = ctypes.CDLL(path)  # already loaded: the same handle
        except OSError:
            continue
        # the symbol is prefixed (and suffixed for 64-bit integers) in numpy's and scipy's builds
        for name in ("openblas_get_corename", "scipy_openblas_get_corename64_", "scipy_openblas_get_corename"):
            fn = getattr(lib, name, None)
            if fn is not None:
                fn.argtypes, fn.restype = [], ctypes.c_char_p
                cores[Path(path).name] = (fn() or b"?").decode()
                break
    return cores


@lru_cache(maxsize=1)
def _drjit_core() -> ctypes.CDLL:
    """Dr.Jit's core library with the LLVM backend's target functions typed. They are C++
    functions (``jit_llvm_set_target`` etc. of ``drjit-core/include/drjit-core/jit.h``) that the
    Python module does not expose: reached by their mangled names."""
    import drjit

    lib = ctypes.CDLL(str(Path(drjit.__path__[0]) / "libdrjit-core.so"))
    lib._Z19jit_llvm_set_targetPKcS0_j.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]
    lib._Z19jit_llvm_set_targetPKcS0_j.restype = None
    for name in ("_Z19jit_llvm_target_cpuv", "_Z24jit_llvm_target_featuresv"):
        getattr(lib, name).argtypes = []
        getattr(lib, name).restype = ctypes.c_char_p
    lib._Z21jit_llvm_vector_widthv.argtypes = []
    lib._Z21jit_llvm_vector_widthv.restype = ctypes.c_uint32
    return lib


def _init_llvm_backend() -> None:
    """Start Dr.Jit's LLVM backend (it starts on first use; its target can only be changed
    after that), or raise RuntimeError where it cannot run."""
    import drjit as dr

    if not dr.has_backend(dr.JitBackend.LLVM):
        raise RuntimeError("Dr.Jit's LLVM backend is not available here (no usable libLLVM)")
    from drjit.llvm import Float

    dr.eval(Float(1.0) + 1.0)


def llvm_target() -> LLVMTarget:
    """What Dr.Jit's LLVM backend compiles for now (starting the backend if it has not)."""
    _init_llvm_backend()
    lib = _drjit_core()
    cpu = lib._Z19jit_llvm_target_cpuv() or b""
    features = lib._Z24jit_llvm_target_featuresv() or b""
    return LLVMTarget(cpu.decode(), features.decode(), int(lib._Z21jit_llvm_vector_widthv()))


def set_llvm_target(target: LLVMTarget) -> LLVMTarget:
    """Make Dr.Jit's LLVM backend compile every later kernel for ``target`` and return the
    target it had (give that back to undo). Raises RuntimeError where the LLVM backend cannot
    run or the target did not take (a Dr.Jit whose function ignores it)."""
    before = llvm_target()
    _drjit_core()._Z19jit_llvm_set_targetPKcS0_j(target.cpu.encode(), target.features.encode(), target.width)
    after = llvm_target()
    if after != target:
        raise RuntimeError(f"Dr.Jit's LLVM target is {after.cpu!r} x{after.width} after setting {target.cpu!r}")
    return before


def emulate_llvm_target(isa: str = "avx2") -> LLVMTarget:
    """Make Dr.Jit's LLVM backend compile every later kernel for ``isa`` (a key of
    :data:`TARGETS`: ``"avx2"``) instead of the host's ISA, and return the target it had.

    Call it before the first kernel that should be emulated: kernels compiled before keep their
    code (Dr.Jit's caches are keyed by the IR, which the target changes, so later code does not
    reuse them; arrays already evaluated keep their values). Dr.Jit loads its libLLVM on first
    use, so the process must have pointed it at the right one before this call
    (``DRJIT_LIBLLVM_PATH``; agrisim's
    :func:`~agrisim.plugins.render.mitsuba.variant.resolve_variant` does). An ISA wider than the
    host's (AVX-512 code on an AVX2 machine) would crash at the first kernel: there is no such
    target here. Raises ValueError for an unknown ``isa``, RuntimeError as
    :func:`set_llvm_target` does.
    """
    target = TARGETS.get(isa.lower())
    if target is None:
        raise ValueError(f"unknown ISA {isa!r} to emulate; known: {', '.join(TARGETS)}")
    return set_llvm_target(target)


def emulate_from_environment() -> LLVMTarget | None:
    """:func:`emulate_llvm_target` for the ISA named by ``$AGRISIM_LLVM_TARGET`` (the host's
    target returned), or None where it is unset or empty."""
    isa = os.environ.get(LLVM_TARGET_ENV, "").strip()
    return emulate_llvm_target(isa) if isa else None
