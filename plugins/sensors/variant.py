"""Which Dr.Jit variant a depth sensor traces on: the one the process already renders with, as
Mitsuba's variant is process-wide (the renderer may have chosen it first)."""

from __future__ import annotations

from agrisim.plugins.render.mitsuba.variant import resolve_variant


def sensor_variant(choice: str) -> str:
    """``choice`` (``auto``, ``cuda`` or ``llvm``), with ``auto`` taking the variant this process
    already uses when there is one; a ConfigError when the choice cannot run here."""
    resolve_variant(choice, "sensor")  # (probes the backends: libLLVM is found first)
    import mitsuba as mi

    current = mi.variant()
    if choice == "auto" and current is not None:
        return "cuda" if current.startswith("cuda") else "llvm"
    return choice
