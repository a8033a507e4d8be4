"""``agrisim doctor``'s report as lines for people (:func:`render_text`), and the reference
figures it measures its speed against."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Reference:
    """A figure of the Performance page's "Measured performance" (docs/performance.md) that doctor measures again here."""

    what: str
    value: float
    unit: str
    bench: str
    """The script in ``bench/`` that measured it."""


#: the machine the reference figures below were measured on (docs/performance.md, "Measured performance":
#: its rows name it; its vector instruction sets were not recorded)
REFERENCE_MACHINE = "AMD EPYC (AVX-512), 2 cores, no GPU, 2026-11-24"
#: one 1080p view of indian cress in the lab, RGB + labels + depth, 4 lights, 1 shadow sample,
#: after the first view (whose kernels compile)
RAYCAST_VIEW = Reference("raycast, one 1080p view", 0.12, "s", "bench/render_views.py")
#: one IK solve from the arm's home to a camera pose around the plant (damped least squares,
#: 200 iterations at most), and one near the current joints (the routine's usual case)
IK_COLD = Reference("IK, one cold solve", 1.6, "ms", "bench/robot_episode.py")
IK_WARM = Reference("IK, one warm solve", 0.04, "ms", "bench/robot_episode.py")

#: a kind with more usable backends than this is summed up by count in the text report
_LIST_AT_MOST = 8


def render_text(report: dict[str, Any]) -> Iterator[str]:
    """The report as lines for people: the machine, the backends, the speed, the verdict."""
    yield f"agrisim {report['agrisim']} doctor: what this machine can run"
    yield ""
    yield "machine"
    py = report["python"]
    yield _row("python", f"{py['version']} ({py['executable']})")
    cpu = report["cpu"]
    yield _row("cpu", f"{cpu['model'] or 'unknown model'}, {cpu['cores']} cores: {_isa(cpu)}")
    yield from _drjit_lines(report["drjit"], cpu)
    cuda = report["drjit"]["cuda"]
    yield _row("gpu, mitsuba", "yes (CUDA variants)" if cuda["usable"] else f"no: {cuda['reason']}")
    torch = report["pytorch"]
    if not torch["installed"]:
        yield _row("gpu, pytorch", "no: PyTorch is not installed (the splat reconstructor needs it)")
    else:
        yield _row(
            "gpu, pytorch", f"PyTorch {torch['version']}: " + ("yes" if torch["cuda"] else f"no: {torch['reason']}")
        )
    ros = report["ros"]
    yield _row("ros 1", _found_line("rospy", ros["ros1"]))
    yield _row("ros 2", _found_line("Cyclone DDS", ros["cyclonedds"]))
    b = report["browser"]
    yield _row("browser", b["path"] if b["found"] else f"none: {b['reason']}; the browser tests skip")
    yield ""
    yield "backends (* the default run's)"
    for kind, rows in report["backends"].items():
        yield from _kind_lines(kind, rows)
    speed = report["speed"]
    if speed is not None:
        yield ""
        yield f"speed here, against docs/performance.md (measured on {speed['reference_machine']})"
        yield from _speed_lines(speed)
        load, cores = speed["load_average"], report["cpu"]["cores"]
        if load is not None and cores and load > cores / 2:
            yield _row("", f"(other work shared the CPU: load average {load:.1f} on {cores} cores; slower for it)")
    yield ""
    verdict = report["default_run"]
    if verdict["ok"]:
        yield "default run (agrisim run): can run here"
    else:
        yield "default run (agrisim run): CANNOT run here"
    for reason in verdict["reasons"]:
        yield f"  {reason}"
    for note in verdict["notes"]:
        yield f"  note: {note}"


_WIDTH = 15


def _row(label: str, text: str) -> str:
    return f"  {label:<{_WIDTH}}{text}"


def _isa(cpu: dict[str, Any]) -> str:
    fma = ", FMA" if cpu["fma"] else ""
    if cpu["avx512"]:
        return f"AVX-512, AVX2{fma}"
    if cpu["avx2"]:
        return f"AVX2{fma}, no AVX-512"
    return "neither AVX2 nor AVX-512"


def _drjit_lines(drjit: dict[str, Any], cpu: dict[str, Any]) -> Iterator[str]:
    if drjit["error"]:
        yield _row("dr.jit", f"no: {drjit['error']}")
        return
    llvm = drjit["llvm"]
    if not llvm["usable"]:
        yield _row("dr.jit", f"{drjit['version']}; no CPU backend: {llvm['reason']}")
    else:
        text = f"{drjit['version']}; CPU backend on LLVM {llvm['libllvm_version'] or '(version unknown)'}"
        if llvm.get("vector_width"):
            isa = "AVX-512" if llvm["target_avx512"] else "AVX2" if llvm["target_avx2"] else "no AVX2"
            text += f", compiling for {llvm['target_cpu']}: {llvm['vector_width']} lanes, {isa}"
            if cpu["avx512"] and not llvm["target_avx512"]:
                text += " (narrower than this CPU)"
        if llvm["reason"]:
            text += f"; {llvm['reason']}"
        yield _row("dr.jit", text)
        yield _row("", f"libLLVM {llvm['libllvm'] or '(not found in this process)'}")
    yield _row("", f"chosen by {llvm['chosen_by']}")


def _found_line(what: str, fact: dict[str, Any]) -> str:
    if not fact["found"]:
        return f"no: {fact['reason']}"
    version = f" {fact['version']}" if fact["version"] else ""
    return f"{what}{version} ({fact['where']})"


def _kind_lines(kind: str, rows: list[dict[str, Any]]) -> Iterator[str]:
    usable = [r for r in rows if r["usable"]]
    names = [r["name"] + ("*" if r["default"] else "") for r in usable]
    if not rows:
        text = "none installed"
    elif len(usable) > _LIST_AT_MOST:
        marked = [n for n in names if n.endswith("*")]
        text = f"{len(usable)} usable" + (f", {', '.join(marked)} among them" if marked else "")
        text += " (agrisim plugins lists them)"
    else:
        text = ", ".join(names) or "none usable"
    yield _row(kind, text)
    for r in rows:
        if not r["usable"]:
            yield _row("", f"{r['name']}{'*' if r['default'] else ''}: no: {r['reason']}")


def _speed_lines(speed: dict[str, Any]) -> Iterator[str]:
    view = speed["raycast_view"]
    if view["error"]:
        yield _row("raycast", f"not timed: {view['error']}")
    else:
        device = "GPU" if str(view.get("variant")).startswith("cuda") else "CPU"
        yield _row("raycast", f"one 1080p view ({device}): {_compare(view['after_first_s'], RAYCAST_VIEW)}")
        yield _row(
            "",
            f"(the mean of {view['views']} views after the first, which took {view['first_s']:.2f} s: "
            "its kernels compiled or read from Dr.Jit's cache)",
        )
    ik = speed["ik"]
    if ik["error"]:
        yield _row("ik", f"not timed: {ik['error']}")
    else:
        yield _row("ik", f"one cold solve (from home): {_compare(ik['cold_ms'], IK_COLD)}")
        yield _row("", f"one warm solve (near the answer): {_compare(ik['warm_ms'], IK_WARM)}")


def _compare(here: float, ref: Reference) -> str:
    digits = 3 if ref.value < 0.1 else 2
    return f"{here:.{digits}f} {ref.unit}, ours {ref.value:g} {ref.unit}: {here / ref.value:.1f}x its time"
