"""``agrisim doctor``: what this machine can run, and how fast, in one report.

It gathers facts (the Python, the CPU and its vector instruction sets, the libLLVM Dr.Jit
loaded, CUDA for Mitsuba and for PyTorch, ROS 1, Cyclone DDS, the browser of the browser tests),
asks every installed backend of every kind whether it can run here, checks the default
``agrisim run`` exactly as the run itself does (:class:`agrisim.episode.Episode` validates it and
writes nothing), and times one 1080p ``raycast`` view and the IK against the figures of the documentation's Performance page.

Backends are asked only through what their providers declare (:class:`agrisim.kinds.BackendSpec`:
``preflight``, capabilities, lazy factories): the core imports no backend. Every probe reports a
failure as a reason; none stops the report. :func:`gather` returns the facts as a JSON-ready
dictionary, :func:`render_text` writes them as lines for people.
"""

from __future__ import annotations

import ctypes
import importlib.metadata
import importlib.util
import os
import platform
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from agrisim.errors import UserError
from agrisim.plugins.apps.doctor_report import IK_COLD, IK_WARM, RAYCAST_VIEW, REFERENCE_MACHINE
from agrisim.plugins.render.mitsuba.cpu import CPUINFO, cpuinfo
from agrisim.version import __version__

#: the headless browsers of the browser tests, in the order tests/browser.py tries them
BROWSERS = ("chromium-headless-shell", "chromium")

#: a plant of an optional extra (PyHelios): when none of its kind is listed, the plugin that
#: would provide it is asked why (``agrisim_plant_unavailable``)
OPTIONAL_PLANT = "helios:tomato"


def gather(timing: bool = True) -> dict[str, Any]:
    """Every fact of the report, JSON-ready; ``timing=False`` skips the two timings (seconds).

    ``report["default_run"]["ok"]`` says whether ``agrisim run`` with its defaults can work here.
    Native libraries' prints to stdout are discarded meanwhile (pybullet's build time), so that
    ``--json`` output stays JSON.
    """
    from agrisim.plugins.native_output import native_output_silenced

    llvm_path_before = os.environ.get("DRJIT_LIBLLVM_PATH")
    with native_output_silenced(stdout=True, stderr=False):
        report: dict[str, Any] = {
            "agrisim": __version__,
            "python": {"version": platform.python_version(), "executable": sys.executable},
            "cpu": cpu_facts(),
        }
        # The default run first: its renderer's preflight points Dr.Jit at the libLLVM agrisim
        # chooses before anything imports Dr.Jit, as in a run.
        episode, report["default_run"] = _check_default_run()
        report["backends"] = _check_backends(episode)
        verdict = report["default_run"]
        # The default run's backends that cannot run here, each named: the episode's own refusal
        # (kept where it says something else) need not say which backend it came from.
        refused, verdict["reasons"] = verdict["reasons"], []
        for kind, rows in report["backends"].items():
            for row in rows:
                if row["default"] and not row["usable"]:
                    label = f"{kind} {row['name']!r}"
                    reason = row["reason"] if row["reason"].startswith(label) else f"{label}: {row['reason']}"
                    verdict["reasons"].append(reason)
        verdict["reasons"] += [r for r in refused if not any(r in reason for reason in verdict["reasons"])]
        verdict["ok"] = not verdict["reasons"]
        report["drjit"] = drjit_facts(llvm_path_before)
        report["pytorch"] = pytorch_facts()
        report["ros"] = ros_facts(report["backends"].get("bridge", []))
        report["browser"] = browser_facts()
        report["speed"] = None
        if timing:
            report["speed"] = _timings(episode)
            view = report["speed"]["raycast_view"]
            if view["error"] and verdict["ok"]:  # a view of the default run failed
                verdict["ok"] = False
                verdict["reasons"].append(f"rendering a view: {view['error']}")
    return report


# ----------------------------------------------------------------------------- the machine


def cpu_facts(path: Path = CPUINFO) -> dict[str, Any]:
    """The CPU's model name and the vector instruction sets its flags list (Linux's ``cpuinfo``)."""
    info = cpuinfo(path)
    model = info.get("model name")
    flags = set(info.get("flags", "").split())
    try:
        cores = len(os.sched_getaffinity(0))  # the cores this process may use, not the host's
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 0
    return {
        "model": model,
        "cores": cores,
        "avx2": "avx2" in flags,
        "fma": "fma" in flags,
        "avx512": "avx512f" in flags,  # the foundation every AVX-512 CPU has
    }


def drjit_facts(llvm_path_before: str | None = None) -> dict[str, Any]:
    """Dr.Jit's version, its LLVM backend (the libLLVM it loaded, its version, the target CPU and
    vector width it compiles for) and whether its CUDA backend (Mitsuba's GPU variants) works.

    ``llvm_path_before``: ``DRJIT_LIBLLVM_PATH`` as it was before agrisim could set it, to say
    who chose the library.
    """
    out: dict[str, Any] = {
        "version": None,
        "error": None,
        "llvm": {"usable": False, "reason": "", "libllvm": None, "libllvm_version": None, "chosen_by": None},
        "cuda": {"usable": False, "reason": ""},
    }
    try:
        import drjit as dr
    except Exception as exc:  # ImportError, or a native library that fails to load
        out["error"] = out["llvm"]["reason"] = out["cuda"]["reason"] = f"drjit does not import: {exc}"
        return out
    out["version"] = getattr(dr, "__version__", None)  # (not in its type stubs)
    llvm = out["llvm"]
    env = os.environ.get("DRJIT_LIBLLVM_PATH")
    if env is None:
        llvm["chosen_by"] = "Dr.Jit's own search (DRJIT_LIBLLVM_PATH unset)"
    elif env == llvm_path_before:
        llvm["chosen_by"] = f"DRJIT_LIBLLVM_PATH={env}, set before agrisim ran"
    else:
        llvm["chosen_by"] = f"DRJIT_LIBLLVM_PATH={env}, agrisim's choice: the newest libLLVM 16+ ldconfig lists"
    llvm["usable"] = bool(dr.has_backend(dr.JitBackend.LLVM))
    if not llvm["usable"]:
        llvm["reason"] = (
            "Dr.Jit found no usable libLLVM (a shared libLLVM 16 or newer: apt-get install libllvm19, which "
            "scripts/setup.sh does, or DRJIT_LIBLLVM_PATH naming the file)"
        )
    else:
        try:
            llvm.update(_llvm_backend())
        except Exception as exc:  # an older or newer Dr.Jit without these symbols: the rest still holds
            llvm["reason"] = f"its target could not be read: {type(exc).__name__}: {exc}"
    out["cuda"]["usable"] = bool(dr.has_backend(dr.JitBackend.CUDA))
    if not out["cuda"]["usable"]:
        driver = "" if shutil.which("nvidia-smi") else " (no NVIDIA driver here: nvidia-smi is not on PATH)"
        out["cuda"]["reason"] = f"Dr.Jit's CUDA backend found no usable NVIDIA GPU{driver}"
    return out


def _llvm_backend() -> dict[str, Any]:
    """The LLVM backend, initialised: the libLLVM mapped into this process and what Dr.Jit
    compiles for (:func:`agrisim.plugins.render.mitsuba.cpu.llvm_target`)."""
    from agrisim.plugins.render.mitsuba.cpu import llvm_target

    target = llvm_target()  # (starts the backend: its target is known from there)
    feature_set = {f[1:] for f in target.features.split(",") if f.startswith("+")}
    path = _loaded_libllvm()
    return {
        "libllvm": path,
        "libllvm_version": _libllvm_version(path) if path else None,
        "target_cpu": target.cpu or None,
        "target_avx512": "avx512f" in feature_set,
        "target_avx2": "avx2" in feature_set,
        "vector_width": target.width,
    }


def _loaded_libllvm() -> str | None:
    """The libLLVM file mapped into this process (the one Dr.Jit loaded), or None."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return None
    found = sorted({line.split()[-1] for line in maps.splitlines() if "/libLLVM" in line})
    named = os.environ.get("DRJIT_LIBLLVM_PATH")
    for path in found:  # another library may map a libLLVM of its own: prefer the one named
        if named and os.path.realpath(path) == os.path.realpath(named):
            return path
    return found[0] if found else None


def _libllvm_version(path: str) -> str | None:
    """LLVM's own version (``LLVMGetVersion``, LLVM 16+), else the one in the file's name."""
    try:
        get = ctypes.CDLL(path).LLVMGetVersion
        parts = [ctypes.c_uint() for _ in range(3)]
        get.restype = None
        get(*(ctypes.byref(p) for p in parts))
        return ".".join(str(p.value) for p in parts)
    except (OSError, AttributeError):
        m = re.search(r"libLLVM(?:-(\d+(?:\.\d+)*))?\.so(?:\.(\d+(?:\.\d+)*))?", path)
        return (m.group(1) or m.group(2)) if m else None


def pytorch_facts() -> dict[str, Any]:
    """Whether PyTorch is installed and sees a CUDA GPU (what the ``splat`` reconstructor needs)."""
    from agrisim.capabilities import cuda_usable

    installed = importlib.util.find_spec("torch") is not None
    version = None
    if installed:
        try:
            version = importlib.metadata.version("torch")
        except importlib.metadata.PackageNotFoundError:
            version = None
    try:
        why = cuda_usable()
    except Exception as exc:  # a torch that fails to import (a broken CUDA library, say)
        why = f"PyTorch does not import: {type(exc).__name__}: {exc}"
    return {"installed": installed, "version": version, "cuda": why is None, "reason": why or ""}


def ros_facts(bridges: list[dict[str, Any]]) -> dict[str, Any]:
    """ROS 1 (rospy) and Cyclone DDS, as the ``ros1`` and ``ros2`` bridges' own checks found them.

    The bridges' preflights import rospy (this environment's, or Debian's:
    ``agrisim.plugins.ros.rospy_env``) and Cyclone DDS; what they imported is what they found,
    and a preflight's refusal is the reason when they did not.
    """
    by_name = {row["name"]: row for row in bridges}

    def found(module: str, bridge: str, version: Callable[[Any], str | None]) -> dict[str, Any]:
        mod = sys.modules.get(module)
        if mod is not None:
            file = getattr(mod, "__file__", None)
            where = str(Path(file).parent) if file else None
            return {"found": True, "where": where, "version": version(mod), "reason": ""}
        if bridge not in by_name:
            return {"found": False, "where": None, "version": None, "reason": f"not checked: no {bridge} bridge"}
        return {"found": False, "where": None, "version": None, "reason": by_name[bridge]["reason"]}

    def distribution(name: str) -> Callable[[Any], str | None]:
        def version(mod: Any) -> str | None:
            try:
                return importlib.metadata.version(name)
            except importlib.metadata.PackageNotFoundError:
                return getattr(mod, "__version__", None)

        return version

    return {
        "ros1": found("rospy", "ros1", distribution("rospy")),
        "cyclonedds": found("cyclonedds", "ros2", distribution("cyclonedds")),
    }


def browser_facts() -> dict[str, Any]:
    """The headless Chromium the browser tests drive (tests/browser.py), or why they skip."""
    path = next((p for name in BROWSERS if (p := shutil.which(name))), None)
    reason = "" if path else f"neither {' nor '.join(BROWSERS)} is on PATH (make test installs {BROWSERS[0]})"
    return {"found": path is not None, "path": path, "reason": reason}


# ----------------------------------------------------------------------------- the backends


def _check_default_run() -> tuple[Any, dict[str, Any]]:
    """(the default run's Episode, or None, and the verdict): every check ``agrisim run`` makes
    before it writes anything (plugins, backends' preflights, the plant, the scene).

    Where its output would go (``runs/`` under the working directory) is a note, not a verdict:
    it says where doctor was started, not what the machine can run.
    """
    from agrisim.config import build_config
    from agrisim.episode import Episode
    from agrisim.files.rundir import resolve_out_dir

    verdict: dict[str, Any] = {"ok": True, "reasons": [], "notes": []}
    try:
        resolve_out_dir(build_config({}))
    except UserError as exc:
        verdict["notes"].append(f"{exc}: agrisim run --out DIR writes elsewhere")
    try:
        # an output directory that passes its checks; an Episode writes nothing before it runs
        with tempfile.TemporaryDirectory() as tmp:
            return Episode(build_config({"output": {"out": str(Path(tmp) / "run")}})), verdict
    except Exception as exc:
        verdict["ok"] = False
        verdict["reasons"].append(_why(exc))
        return None, verdict


def _check_backends(episode: Any) -> dict[str, list[dict[str, Any]]]:
    """Every installed backend of every kind: usable here, or why not, and whether the default
    run uses it. A backend is usable when its options validate at their defaults, its
    declared needs (a CUDA GPU) are met, its preflight passes and its implementation imports."""
    from agrisim.capabilities import cuda_usable
    from agrisim.config import backend_options, build_config
    from agrisim.kinds import KINDS, LazyFactory
    from agrisim.registry import Registry, make_plugin_manager

    config = build_config({})
    try:
        registry = episode.registry if episode is not None else Registry(make_plugin_manager())
    except Exception as exc:  # a broken plugin: nothing can be listed
        return {"plugins": [_unusable("(discovery)", _why(exc), default=True)]}
    out: dict[str, list[dict[str, Any]]] = {}
    for kind, info in KINDS.items():
        rows: list[dict[str, Any]] = []
        try:
            specs = registry.specs(kind)
        except Exception as exc:
            out[kind] = [_unusable("(discovery)", _why(exc))]
            continue
        choice = getattr(config, info.section) if info.section else None
        for name, spec in specs.items():
            if choice is not None:
                table, default = choice.options_for(name), name == choice.backend
            elif kind == "sink":  # every sink observes every run
                table, default = config.sink.get(name, {}), True
            else:
                table, default = {}, kind == "plant" and name == config.plant
            reason = ""
            try:
                options = backend_options(spec.options_model, table, f"{kind} backend {name!r}")
                if getattr(spec.capabilities, "needs_cuda", False):
                    why = cuda_usable()
                    if why is not None:
                        raise UserError(f"needs a CUDA GPU: {why}")
                if spec.preflight is not None:
                    spec.preflight(config, options)
                if isinstance(spec.factory, LazyFactory):
                    try:
                        spec.factory.resolve()
                    except Exception as exc:
                        raise UserError(f"its implementation does not import: {_why(exc)}") from None
            except Exception as exc:
                reason = _why(exc)
            rows.append(
                {
                    "name": name,
                    "usable": not reason,
                    "reason": reason,
                    "default": default,
                    "distribution": spec.distribution,
                }
            )
        if kind == "plant" and not any(n.startswith(OPTIONAL_PLANT.split(":")[0] + ":") for n in specs):
            try:
                hints = [h for h in registry.pm.hook.agrisim_plant_unavailable(name=OPTIONAL_PLANT) if h]
            except Exception:  # a plugin's broken hint hides nothing else
                hints = []
            if hints:
                prefix = OPTIONAL_PLANT.split(":")[0]
                rows.append(_unusable(f"{prefix}:*", hints[0]))
        out[kind] = rows
    return out


def _unusable(name: str, reason: str, default: bool = False) -> dict[str, Any]:
    """A row for what is not one installed backend: a discovery that failed, a plugin's hint."""
    return {"name": name, "usable": False, "reason": reason, "default": default, "distribution": ""}


def _why(exc: BaseException) -> str:
    """One line: a refusal's own message, anything else with its type."""
    if isinstance(exc, UserError):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


# ----------------------------------------------------------------------------- the timings


def _timings(episode: Any) -> dict[str, Any]:
    # Other work on a shared machine slows both: said beside them, not corrected for (read
    # before they run, so that it counts the others' work, not theirs).
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {
        "reference_machine": REFERENCE_MACHINE,
        "load_average": load,
        "raycast_view": _time_raycast_view(episode),
        "ik": _time_ik(),
    }


def _time_raycast_view(episode: Any, later_views: int = 2) -> dict[str, Any]:
    """One 1080p ``raycast`` view of the default run's scene (indian cress in the lab, the arms
    at home), as bench/render_views.py times it: the first view (its kernels compile, or load
    from Dr.Jit's cache), then the mean of ``later_views`` others."""
    out: dict[str, Any] = {"reference_s": RAYCAST_VIEW.value, "first_s": None, "after_first_s": None, "error": None}
    if episode is None or episode.scene is None:
        out["error"] = "the default run cannot work here (see above)"
        return out
    import numpy as np

    from agrisim.config import backend_options

    try:
        spec = episode.registry.get("renderer", "raycast")
        options = (
            episode.renderer_options
            if episode.renderer_spec is not None and episode.renderer_spec.name == "raycast"
            else backend_options(spec.options_model, episode.config.renderer.options_for("raycast"), "raycast")
        )
        renderer = episode.registry.build("renderer", spec, episode.scene, episode.cell, episode.config.render, options)
        try:
            poses = {arm.name: episode.kinematics[arm.name].link_poses(np.array(arm.home)) for arm in episode.cell.arms}
            setpoints = next(iter(episode.setpoints.values()))
            views = [
                setpoints[i].world_T_camera for i in np.linspace(0, len(setpoints) - 1, later_views + 1).astype(int)
            ]
            out["resolution"] = f"{episode.camera.width}x{episode.camera.height}"
            mitsuba = sys.modules.get("mitsuba")  # raycast traces with Mitsuba's variant: llvm_* or cuda_*
            out["variant"] = mitsuba.variant() if mitsuba is not None else None
            t0 = time.perf_counter()
            renderer.render(episode.camera, views[0], poses)
            out["first_s"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            for T in views[1:]:
                renderer.render(episode.camera, T, poses)
            out["after_first_s"] = (time.perf_counter() - t0) / later_views
            out["views"] = later_views
        finally:
            renderer.close()
    except Exception as exc:
        out["error"] = _why(exc)
    return out


def _time_ik() -> dict[str, Any]:
    """IK on the first arm, as bench/robot_episode.py times it: one solve from home to a camera
    pose 0.5 m from the plant (the mean of 50), and one from joints near the answer (of 200)."""
    out: dict[str, Any] = {
        "reference_cold_ms": IK_COLD.value,
        "reference_warm_ms": IK_WARM.value,
        "cold_ms": None,
        "warm_ms": None,
        "error": None,
    }
    try:
        import numpy as np

        from agrisim.config import RunConfig
        from agrisim.robot.kinematics import ArmKinematics
        from agrisim.robot.setpoints import random_views
        from agrisim.validation import open_rig

        _, cell = open_rig(RunConfig())  # the default rig's
        k = ArmKinematics(cell.arms[0])
        rng = np.random.default_rng(0)
        home = np.array(cell.arms[0].home)
        targets = random_views(cell.plant_center, rng)[:2]  # the bench's 50 targets (the first two used)
        solved = [k.ik(T, home, rng=rng).q for T in targets]
        # The Performance page's cold figure is of the solver loop itself (no restarts): the same call here.
        out["cold_ms"] = _per_call_ms(lambda: k.solve(targets[0], home, 200, 1e-7), 50)
        q = solved[1]
        if q is None:
            raise RuntimeError("IK found no solution for the warm-start target")
        out["warm_ms"] = _per_call_ms(lambda: k.ik(k.fk(q + 0.01), q, rng=rng), 200)
    except Exception as exc:
        out["error"] = _why(exc)
    return out


def _per_call_ms(fn: Callable[[], object], n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n * 1e3


# ----------------------------------------------------------------------------- the report
