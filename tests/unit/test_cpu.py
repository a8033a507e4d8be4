"""agrisim.plugins.render.mitsuba.cpu: the host's vector ISA from /proc/cpuinfo, and Dr.Jit's LLVM backend compiling
for AVX2 on request (what ``AGRISIM_TEST_CPU=avx2`` runs the suite with): its kernels' IR, not
only its settings, say 8 lanes of AVX2."""

from __future__ import annotations

import pytest

from agrisim.plugins.render.mitsuba import cpu


@pytest.mark.parametrize(
    "flags, isa",
    [
        ("fpu sse2 sse4_2 avx avx2 fma avx512f avx512vl", "AVX-512"),
        ("fpu sse2 sse4_2 avx avx2 fma avx512f", "AVX2"),  # no AVX512VL: Dr.Jit stays at 8 lanes
        ("fpu sse2 sse4_2 avx avx2 fma", "AVX2"),
        ("fpu sse2 sse4_2 avx", "AVX"),
        ("fpu sse2 sse4_2", "SSE4.2"),
        ("fpu sse2", "SSE2"),
        ("", "unknown"),
    ],
)
def test_vector_isa_reads_the_flags(monkeypatch: pytest.MonkeyPatch, flags: str, isa: str) -> None:
    monkeypatch.setattr(cpu, "cpuinfo", lambda path=cpu.CPUINFO: {"model name": "Some CPU", "flags": flags})
    assert cpu.vector_isa() == isa
    assert cpu.cpu_model() == "Some CPU"


def test_arm_features_and_the_host() -> None:
    assert cpu.vector_isa() in {"AVX-512", "AVX2", "AVX", "SSE4.2", "SSE2", "NEON", "unknown"}
    assert cpu.cpu_model()
    with pytest.raises(ValueError, match="unknown ISA 'avx9'"):
        cpu.emulate_llvm_target("avx9")


def test_emulated_avx2_kernels_are_eight_lanes_of_avx2() -> None:
    """After emulate_llvm_target("avx2"), a kernel's IR is 8 lanes wide, for LLVM's x86-64-v3,
    and picks AVX's approximate reciprocal square root (``normalize``'s) where AVX-512 has its
    own; given back, the target is the one before."""
    from agrisim.errors import ConfigError
    from agrisim.plugins.render.mitsuba.variant import resolve_variant

    try:
        resolve_variant("llvm")  # Dr.Jit pointed at its libLLVM first, as a renderer does
    except ConfigError as exc:
        pytest.skip(str(exc))
    if cpu.vector_isa() not in ("AVX2", "AVX-512"):
        pytest.skip("AVX2 code cannot run on this CPU")
    import drjit as dr
    from drjit.llvm import Array3f, Float

    before = cpu.emulate_llvm_target("avx2")
    try:
        assert cpu.llvm_target() == cpu.TARGETS["avx2"]
        dr.kernel_history()  # (empties it)
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            x = dr.arange(Float, 1000) * 0.37 + 1.0
            dr.eval(dr.normalize(Array3f(x, 2.0 * x, x + 3.0)))
            ir = "".join(k["ir"].getvalue() for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT)
    finally:
        cpu.set_llvm_target(before)
    assert cpu.llvm_target() == before
    assert "<8 x float>" in ir and "<16 x float>" not in ir
    assert '"target-cpu"="x86-64-v3"' in ir
    assert "@llvm.x86.avx.rsqrt.ps.256" in ir and "avx512" not in ir.replace("-avx512", "")
