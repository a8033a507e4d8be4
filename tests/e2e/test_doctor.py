"""``agrisim doctor``: what it says about this machine is true (against /proc/cpuinfo, the installed
packages, the registry, the tests' own browser lookup), what it says without a GPU and ROS, and
its exit status 1 where the default run cannot work.

The command runs in a fresh interpreter (Dr.Jit's backends are chosen once per process), with
packages hidden by ``sys.modules[name] = None`` before agrisim starts. Timings are never checked,
only that they were taken; facts are checked against independent truth, so these hold on any
x86-64 machine, with or without AVX-512, a GPU or ROS.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import platform
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from browser import browser

from agrisim.plugins.apps.doctor import cpu_facts
from agrisim.plugins.apps.doctor_report import IK_COLD, IK_WARM, RAYCAST_VIEW, REFERENCE_MACHINE, render_text

REPO = Path(__file__).resolve().parents[2]
CPUINFO = Path("/proc/cpuinfo")


def doctor(
    cwd: Path, *args: str, hide: tuple[str, ...] = (), env: dict[str, str] | None = None
) -> tuple[int, str, str]:
    """``agrisim doctor ARGS`` in a fresh Python with the modules ``hide`` unimportable."""
    code = (
        "import sys\n"
        f"for name in {hide!r}:\n"
        "    sys.modules[name] = None  # import raises ImportError, find_spec answers None\n"
        "from agrisim.app.cli import main\n"
        f"sys.exit(main(['doctor', *{list(args)!r}]))\n"
    )
    environ = {
        k: v for k, v in os.environ.items() if k not in ("AGRISIM_LOAD_PLUGINS", "AGRISIM_DISABLE_PLUGIN_AUTOLOAD")
    }
    environ.update(env or {})
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=cwd, env=environ, capture_output=True, text=True, timeout=300
    )
    return proc.returncode, proc.stdout, proc.stderr


def cpuinfo() -> tuple[str | None, set[str]]:
    """The first processor's model name and flags, read here."""
    text = CPUINFO.read_text()
    model = re.search(r"^model name\s*:\s*(.*)$", text, re.M)
    flags = re.search(r"^flags\s*:\s*(.*)$", text, re.M)
    return (model.group(1).strip() if model else None), set(flags.group(1).split() if flags else ())


def rows(report: dict[str, Any], kind: str) -> dict[str, dict[str, Any]]:
    return {r["name"]: r for r in report["backends"][kind]}


@pytest.mark.skipif(not CPUINFO.exists(), reason="needs Linux's /proc/cpuinfo")
def test_doctor_tells_the_truth_about_this_machine(tmp_path: Path) -> None:
    code, out, err = doctor(tmp_path, "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["default_run"] == {"ok": True, "reasons": [], "notes": []}

    assert report["python"]["version"] == platform.python_version()
    model, flags = cpuinfo()
    cpu = report["cpu"]
    assert cpu["model"] == model
    assert cpu["avx512"] == ("avx512f" in flags)
    assert cpu["avx2"] == ("avx2" in flags)
    assert cpu["fma"] == ("fma" in flags)
    assert cpu["cores"] == len(os.sched_getaffinity(0))

    drjit = report["drjit"]
    assert drjit["version"] == importlib.metadata.version("drjit")
    llvm = drjit["llvm"]
    if llvm["usable"]:
        assert Path(llvm["libllvm"]).is_file()
        major = llvm["libllvm_version"].split(".")[0]
        assert re.search(rf"libLLVM(-{major}[.\d]*\.so|\.so\.{major}\b)", Path(llvm["libllvm"]).name), llvm
        assert llvm["vector_width"] in (4, 8, 16)
        assert llvm["target_cpu"]
        assert not (llvm["target_avx512"] and not cpu["avx512"])  # never wider than the CPU

    torch = report["pytorch"]
    assert torch["installed"] == (importlib.util.find_spec("torch") is not None)
    assert report["ros"]["cyclonedds"]["found"] == (importlib.util.find_spec("cyclonedds") is not None)
    ros1 = report["ros"]["ros1"]
    debian = Path("/usr/lib/python3/dist-packages/rospy").is_dir()
    if ros1["found"]:
        assert (Path(ros1["where"]) / "__init__.py").is_file()
    else:
        assert ros1["reason"]
        assert importlib.util.find_spec("rospy") is None
    assert report["browser"]["path"] == browser()
    assert report["browser"]["found"] == (browser() is not None)
    if not debian and importlib.util.find_spec("rospy") is None:
        assert not ros1["found"]

    # every installed backend, as the registry lists them; the default run's marked and usable
    from agrisim.registry import PROVIDER_HOOKS, Registry, make_plugin_manager

    registry = Registry(make_plugin_manager())
    for kind in PROVIDER_HOOKS:
        listed = {n for n in rows(report, kind) if not n.endswith(":*")}
        assert listed == set(registry.specs(kind)), kind
    defaults = {(kind, name) for kind in PROVIDER_HOOKS for name, row in rows(report, kind).items() if row["default"]}
    assert {
        ("physics", "pybullet"),
        ("renderer", "raycast"),
        ("sensor", "exact"),
        ("planner", "ompl"),
        ("reconstructor", "pointcloud"),
        ("sink", "dataset"),
        ("sink", "rerun"),
        ("plant", "indian_cress"),
        ("room", "lab"),
        ("rig", "paper"),
    } == defaults
    for kind, name in defaults:
        assert rows(report, kind)[name]["usable"], (kind, name)
    splat = rows(report, "reconstructor")["splat"]
    can_splat = torch["cuda"] and importlib.util.find_spec("gsplat") is not None
    assert splat["usable"] == can_splat, splat
    assert splat["usable"] or splat["reason"]

    # timed, beside the Performance page's figures (the figures themselves are not checked: machines differ)
    speed = report["speed"]
    assert speed["reference_machine"] == REFERENCE_MACHINE
    view, ik = speed["raycast_view"], speed["ik"]
    assert view["error"] is None and ik["error"] is None
    assert view["first_s"] > 0 and view["after_first_s"] > 0 and view["resolution"] == "1920x1080"
    assert view["reference_s"] == RAYCAST_VIEW.value
    assert ik["cold_ms"] > 0 and ik["warm_ms"] > 0
    assert (ik["reference_cold_ms"], ik["reference_warm_ms"]) == (IK_COLD.value, IK_WARM.value)

    # the text says the same
    text = "\n".join(render_text(report))
    assert f"{model}, {cpu['cores']} cores" in text
    assert ("AVX-512," in text) == cpu["avx512"]
    assert "default run (agrisim run): can run here" in text
    assert f"ours {RAYCAST_VIEW.value:g} s" in text and f"ours {IK_COLD.value:g} ms" in text


def test_doctor_prints_a_report_and_exits_0(cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The command as users run it (in-process, text, no timings)."""
    monkeypatch.chdir(tmp_path)
    code, out, err = cli(["doctor", "--no-timing"])
    assert code == 0, err
    lines = out.splitlines()
    cpu = next(line for line in lines if line.strip().startswith("cpu "))
    model, flags = cpuinfo() if CPUINFO.exists() else (None, set())
    assert (model or "unknown model") in cpu
    assert ("AVX-512," in cpu) == ("avx512f" in flags)
    assert "no AVX-512" in cpu or "avx512f" in flags or "avx2" not in flags
    assert lines[-1] == "default run (agrisim run): can run here"
    assert not any(line.startswith("speed") for line in lines)
    assert not (tmp_path / "runs").exists()  # it checks the default run; it writes nothing


def test_without_a_gpu_or_ros_doctor_says_so_and_still_passes(tmp_path: Path) -> None:
    hidden = ("torch", "gsplat", "rospy", "cyclonedds")
    code, out, err = doctor(tmp_path, "--json", "--no-timing", hide=hidden, env={"CUDA_VISIBLE_DEVICES": ""})
    assert code == 0, err  # nothing the default run needs is missing
    report = json.loads(out)
    assert report["default_run"]["ok"]
    assert report["speed"] is None

    assert report["pytorch"] == {
        "installed": False,
        "version": None,
        "cuda": False,
        "reason": "PyTorch is not installed",
    }
    cuda = report["drjit"]["cuda"]
    assert not cuda["usable"] and "no usable NVIDIA GPU" in cuda["reason"]
    splat = rows(report, "reconstructor")["splat"]
    assert not splat["usable"] and "CUDA GPU" in splat["reason"]

    ros1, dds = report["ros"]["ros1"], report["ros"]["cyclonedds"]
    assert not ros1["found"] and ("ROS 1" in ros1["reason"] or "rospy" in ros1["reason"])
    assert not dds["found"] and "Cyclone DDS" in dds["reason"]
    bridges = rows(report, "bridge")
    assert not bridges["ros1"]["usable"] and bridges["ros1"]["reason"] == ros1["reason"]
    assert not bridges["ros2"]["usable"] and bridges["ros2"]["reason"] == dds["reason"]

    text = "\n".join(render_text(report))
    assert "gpu, pytorch   no: PyTorch is not installed" in text
    assert f"ros 1          no: {ros1['reason']}" in text
    assert f"ros 2          no: {dds['reason']}" in text
    assert "splat: no: needs a CUDA GPU: PyTorch is not installed" in text
    assert text.endswith("default run (agrisim run): can run here")


@pytest.mark.parametrize(
    ("hide", "env", "why"),
    [
        pytest.param(
            (), {"DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM.so"}, "no usable libLLVM", id="libllvm-unfindable"
        ),
        pytest.param(("drjit",), {}, "drjit", id="drjit-unimportable"),
    ],
)
def test_where_the_default_run_cannot_work_doctor_exits_1_naming_why(
    tmp_path: Path, hide: tuple[str, ...], env: dict[str, str], why: str
) -> None:
    env = {**env, "CUDA_VISIBLE_DEVICES": ""}  # else a GPU would render instead
    code, out, err = doctor(tmp_path, "--no-timing", hide=hide, env=env)
    assert code == 1, out + err
    assert "Traceback" not in err
    verdict = out[out.index("default run (agrisim run): CANNOT run here") :].splitlines()
    assert len(verdict) >= 2 and all(line.startswith("  ") for line in verdict[1:])
    assert any("raycast" in line and why in line for line in verdict[1:]), verdict
    assert re.search(rf"^\s+raycast\*: no: .*{why}", out, re.M), out
    code, out, err = doctor(tmp_path, "--json", "--no-timing", hide=hide, env=env)
    assert code == 1
    report = json.loads(out)
    assert not report["default_run"]["ok"] and not rows(report, "renderer")["raycast"]["usable"]


def test_a_bad_flag_exits_2_with_one_line(cli) -> None:
    code, out, err = cli(["doctor", "--bogus"])
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("agrisim: error: ") and "--bogus" in err


def test_an_avx2_only_cpu_is_told_apart(tmp_path: Path) -> None:
    """The flags decide, not this machine: an AVX2 CPU without AVX-512, and one with neither."""
    info = tmp_path / "cpuinfo"
    info.write_text("processor\t: 0\nmodel name\t: AMD EPYC 7B13\nflags\t\t: fpu sse2 avx avx2 fma\n\n")
    facts = cpu_facts(info)
    assert facts | {"cores": 0} == {"model": "AMD EPYC 7B13", "cores": 0, "avx2": True, "fma": True, "avx512": False}
    info.write_text("processor\t: 0\nmodel name\t: Old\nflags\t\t: fpu sse2 avx\n\n")
    assert not cpu_facts(info)["avx2"]
    assert cpu_facts(tmp_path / "missing") | {"cores": 0} == {
        "model": None,
        "cores": 0,
        "avx2": False,
        "fma": False,
        "avx512": False,
    }


def test_the_reference_figures_are_the_readmes() -> None:
    """doctor's reference figures are the "Measured performance" rows of the docs, on the
    machine that page names for them; the README points new users at the command."""
    readme = (REPO / "README.md").read_text()
    perf = (REPO / "docs" / "performance.md").read_text()
    view = next(line for line in perf.splitlines() if line.startswith("| one 1080p view, RGB + labels + depth"))
    cpu = REFERENCE_MACHINE.split(", ")[0]  # its model and vector ISA, as that page names them
    assert f"| {RAYCAST_VIEW.value:g} s / " in view and cpu in view and RAYCAST_VIEW.bench in view
    ik = next(line for line in perf.splitlines() if line.startswith("| IK, one cold solve / warm"))
    assert f"| {IK_COLD.value:g} ms / {IK_WARM.value:g} ms" in ik and "(same)" in ik
    robot = next(line for line in perf.splitlines() if line.startswith("| robot-only episode in one process"))
    assert cpu in robot and IK_COLD.bench in robot  # the row "(same)" refers to
    assert cpu.endswith(("(AVX2)", "(AVX-512)")) and f"**{cpu}**" in perf  # a machine the section describes
    assert "`agrisim doctor`" in readme[: readme.index("## Two commands")]
    cli_block = readme[readme.index("## The command line") :]
    assert "agrisim doctor" in cli_block[: cli_block.index("```\n\n")]
