"""Shared fixtures: the paper's cell and its arms' kinematics (built once per session), the CLI run
in-process (``cli``), and a plugin that keeps every rendered frame (``frames``). Tests marked
``gpu`` are skipped where Mitsuba finds no usable NVIDIA GPU (CI).

The suite as another CPU would run it: ``AGRISIM_TEST_CPU=avx2`` (on an AVX-512 machine) makes
Dr.Jit's LLVM backend, on which ``raycast`` and ``mitsuba`` render, compile every kernel for AVX2
8 lanes wide, as on an AVX2 machine (AMD EPYC before Zen 4), from the session's start, in this
process and in the agrisim processes that tests start (it sets ``AGRISIM_LLVM_TARGET``, which
:func:`isolated_env` keeps). OpenBLAS and numpy choose their kernels when they load, before any
conftest runs, so their settings must come with it from the shell (the session refuses to start
without them): ``OPENBLAS_CORETYPE=Haswell`` (OpenBLAS's AVX2 kernels, numpy's and scipy's) and
``NPY_DISABLE_CPU_FEATURES`` naming numpy's AVX-512 targets (with numpy 2.4)::

    AGRISIM_TEST_CPU=avx2 OPENBLAS_CORETYPE=Haswell NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" \
        .venv/bin/python -m pytest -q tests

The header of the session says what it runs on (the CPU, and the emulated target). What stays
the host's: Embree's and Open Image Denoise's kernels (chosen from CPUID) and the results of
approximate instructions (:mod:`agrisim.plugins.render.mitsuba.cpu`).
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

from agrisim.config import RunConfig
from agrisim.interfaces import Frame
from agrisim.registry import hookimpl
from agrisim.robot.cell import Cell
from agrisim.robot.kinematics import ArmKinematics
from agrisim.scene.model import Label, LabelTable, Material, Mesh
from agrisim.validation import open_rig


def _cuda_usable() -> bool:
    from agrisim.errors import ConfigError
    from agrisim.plugins.render.mitsuba.variant import resolve_variant

    try:  # (through agrisim, which points Dr.Jit at the right libLLVM before importing it)
        resolve_variant("cuda")
    except ConfigError:
        return False
    return True


#: the variable that asks for the emulation, and the OpenBLAS core that must come with each ISA
TEST_CPU_ENV = "AGRISIM_TEST_CPU"
_OPENBLAS_CORE = {"avx2": "Haswell"}
#: the ISA emulated in this session ("": none), kept here: tests may clear AGRISIM_ variables
_emulated = ""


def pytest_configure(config: pytest.Config) -> None:
    """``AGRISIM_TEST_CPU``: set Dr.Jit's LLVM target before any test compiles a kernel."""
    global _emulated
    isa = os.environ.get(TEST_CPU_ENV, "").strip().lower()
    if not isa:
        return
    from agrisim.plugins.render.mitsuba.cpu import LLVM_TARGET_ENV, TARGETS

    if isa not in TARGETS:
        raise pytest.UsageError(f"{TEST_CPU_ENV}={isa}: unknown; known: {', '.join(TARGETS)}")
    core = _OPENBLAS_CORE[isa]
    if os.environ.get("OPENBLAS_CORETYPE", "").lower() != core.lower():
        raise pytest.UsageError(
            f"{TEST_CPU_ENV}={isa} needs OPENBLAS_CORETYPE={core} from the shell (OpenBLAS reads it when it loads)"
        )
    from agrisim.plugins.render.mitsuba.cpu import numpy_simd, numpy_wide_targets

    if wide := [t for t in numpy_wide_targets() if t in numpy_simd()[1]]:
        raise pytest.UsageError(
            f"{TEST_CPU_ENV}={isa}: numpy uses its {', '.join(wide)} loops; set "
            f'NPY_DISABLE_CPU_FEATURES="{" ".join(numpy_wide_targets())}" in the shell (numpy reads it when it loads)'
        )
    os.environ[LLVM_TARGET_ENV] = isa  # for this process (read once, below) and every child
    from agrisim.errors import ConfigError
    from agrisim.plugins.render.mitsuba.variant import resolve_variant

    try:  # Dr.Jit set up as a renderer sets it up: its libLLVM, then the target
        resolve_variant("llvm")
    except ConfigError as exc:
        raise pytest.UsageError(f"{TEST_CPU_ENV}={isa}: {exc}") from None
    _emulated = isa


def pytest_report_header(config: pytest.Config) -> list[str]:
    from agrisim.plugins.render.mitsuba.cpu import cpu_model, numpy_simd, openblas_cores, vector_isa

    cores = ", ".join(sorted(set(openblas_cores().values()))) or "not loaded"
    used = numpy_simd()[1]
    lines = [
        f"cpu: {cpu_model()} ({vector_isa()}); OpenBLAS kernels: {cores}; numpy SIMD: {used[-1] if used else 'baseline'}"
    ]
    if _emulated:
        from agrisim.plugins.render.mitsuba.cpu import llvm_target

        target = llvm_target()
        lines.append(
            f"emulating {_emulated}: Dr.Jit LLVM target {target.cpu}, {target.width} lanes "
            f"(host's Embree and Open Image Denoise kernels stay)"
        )
    return lines


def isolated_env(**extra: str) -> dict[str, str]:
    """The environment for an agrisim subprocess that must not see the caller's ``AGRISIM_``
    settings: ``os.environ`` without them, except the emulated CPU (``AGRISIM_LLVM_TARGET``, set
    by ``AGRISIM_TEST_CPU``: the child computes as this process does) and the session's plant
    cache (which changes no result); ``extra`` on top."""
    from agrisim.plugins.render.mitsuba.cpu import LLVM_TARGET_ENV
    from agrisim.scene.plant_cache import PLANT_CACHE_ENV

    env = {k: v for k, v in os.environ.items() if not k.startswith("AGRISIM_") or k == PLANT_CACHE_ENV}
    if _emulated:  # from the session, not os.environ: a test's monkeypatch may have cleared it
        env[LLVM_TARGET_ENV] = _emulated
    env.update(extra)
    return env


@contextlib.contextmanager
def installed(package: Path, site: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[str, str]]:
    """A test package (a folder with its ``pyproject.toml`` and modules) installed as pip lays it
    out, in ``site`` on ``sys.path``: its modules, a dist-info with its metadata and ``agrisim``
    entry points. agrisim's plugin switches are cleared meanwhile; its modules are forgotten
    afterwards. Yields (distribution name, version)."""
    import sys

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib

    pyproject = tomllib.loads((package / "pyproject.toml").read_text())
    project, modules = pyproject["project"], pyproject["tool"]["setuptools"]["py-modules"]
    info = site / f"{project['name'].replace('-', '_')}-{project['version']}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n")
    points = "".join(f"{k} = {v}\n" for k, v in project["entry-points"]["agrisim"].items())
    (info / "entry_points.txt").write_text(f"[agrisim]\n{points}")
    for module in modules:
        shutil.copyfile(package / f"{module}.py", site / f"{module}.py")
    monkeypatch.syspath_prepend(str(site))
    for var in ("AGRISIM_DISABLE_PLUGIN_AUTOLOAD", "AGRISIM_LOAD_PLUGINS", "AGRISIM_TRACE_PLUGINS"):
        monkeypatch.delenv(var, raising=False)
    try:
        yield project["name"], project["version"]
    finally:
        for module in modules:
            sys.modules.pop(module, None)


@contextlib.contextmanager
def local_ray(module: str, **resources: float) -> Iterator[None]:
    """A quiet local Ray of two CPUs on loopback, with ``resources`` (custom resources standing
    in for GPUs: Ray places tasks by them as by its own); ``module``'s functions travel to the
    workers by value (they cannot import a test module)."""
    import logging
    import sys

    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    import ray

    ray.init(
        address="local",
        num_cpus=2,
        resources=resources,
        object_store_memory=128 * 2**20,
        include_dashboard=False,
        log_to_driver=False,
        logging_level=logging.ERROR,
        _node_ip_address="127.0.0.1",
    )
    ray.cloudpickle.register_pickle_by_value(sys.modules[module])
    try:
        yield
    finally:
        ray.shutdown()


#: the heaviest test modules' time, seconds under the AVX2 emulation (bench/suite_profile.py,
#: 2026-11-29; the rest take less than 10). They are collected heaviest first and, with
#: ``--no-loadscope-reorder`` (the Makefile's), xdist hands modules out in that order: the two
#: workers end within a short module of each other, where the path tracer's module, collected
#: late, kept one busy for a minute after the other had finished.
MODULE_SECONDS = {
    "tests/unit/test_render_mitsuba.py": 166,
    "tests/e2e/test_render_command.py": 78,
    "tests/e2e/test_compare.py": 58,
    "tests/e2e/test_colmap.py": 56,  # 18 views since 2026-11-29 (99 with 36)
    "tests/e2e/test_web_view.py": 51,
    "tests/contracts/test_contracts.py": 40,
    "tests/e2e/test_helios.py": 39,
    "tests/e2e/test_docs_snippets.py": 36,
    "tests/e2e/test_sweep_cluster.py": 34,
    "tests/e2e/test_sweep.py": 33,
    "tests/e2e/test_recon.py": 25,
    "tests/e2e/test_nextview_command.py": 35,
    "tests/e2e/test_resume.py": 22,
    "tests/e2e/test_bench.py": 20,
    "tests/e2e/test_bench_eval.py": 16,  # measured 13-16 s on the 2-core Xeon (AVX-512), not under the emulation
    "tests/e2e/test_plant_view_env.py": 22,
    "tests/unit/test_plants.py": 20,
    "tests/e2e/test_docs_site.py": 19,
    "tests/e2e/test_traits_command.py": 19,
    "tests/e2e/test_single_arm.py": 18,
    "tests/unit/test_arm_visuals.py": 17,
    "tests/e2e/test_reliability.py": 17,
    "tests/unit/test_exact_pass_agreement.py": 16,
    "tests/e2e/test_depth_sensor_runs.py": 16,
    "tests/e2e/test_ros1.py": 15,
    "tests/e2e/test_episode.py": 14,
    "tests/e2e/test_ros2.py": 13,
    "tests/e2e/test_wheel.py": 13,
    "tests/e2e/test_bench_exports.py": 13,
    "tests/unit/test_plant_surfaces.py": 13,
    "tests/unit/test_render_raycast.py": 13,
    "tests/e2e/test_turntable.py": 12,
    "tests/e2e/test_gantry.py": 10,
}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # heaviest modules first (a stable sort: within a module, and among the light ones, as collected)
    items[:] = sorted(items, key=lambda item: -MODULE_SECONDS.get(item.nodeid.split("::")[0], 0))
    gpu = [item for item in items if "gpu" in item.keywords]
    if gpu and not _cuda_usable():
        skip = pytest.mark.skip(reason="needs an NVIDIA GPU usable by Mitsuba (run on the GPU machine)")
        for item in gpu:
            item.add_marker(skip)


@pytest.fixture(scope="session", autouse=True)
def plant_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """One grown plant per species, options and seed for the whole session, kept on disk
    (``AGRISIM_PLANT_CACHE``) in a folder every xdist worker of this run shares, and the
    processes tests start (runs, Ray's workers) inherit. Fresh each session: a change to a
    species' code is never hidden. Tests of growing itself call the growers directly, or
    turn the cache off."""
    from agrisim.scene.plant_cache import PLANT_CACHE_ENV

    base = tmp_path_factory.getbasetemp()
    folder = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "plant-cache"
    folder.mkdir(exist_ok=True)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(PLANT_CACHE_ENV, str(folder))
        yield str(folder)


@pytest.fixture(scope="session")
def cell() -> Cell:
    """The default rig's cell (the paper's), as a run gets it: through the registry."""
    return open_rig(RunConfig())[1]


@pytest.fixture(scope="session")
def kin(cell: Cell) -> dict[str, ArmKinematics]:
    return {arm.name: ArmKinematics(arm) for arm in cell.arms}


def small_run(out, **sections):  # noqa: ANN001, ANN201
    """Run a small complete episode into ``out`` and return it: kinematic arms, 1x3 setpoints
    (every one reached without an OMPL search), 320x180, raycast without shadow rays, no
    recording; ``sections`` (``plant="..."``, ``render={...}``, ``recon={...}``) go on top."""
    from agrisim.config import build_config, merge
    from agrisim.episode import Episode

    base = {
        "renderer": {"raycast": {"shadow_samples": 0}},
        "physics": {"backend": "kinematic"},
        "routine": {"setpoints": "1x3"},
        "camera": {"resolution": "320x180"},
        "output": {"out": str(out), "no_rrd": True},
    }
    _, summary = Episode(build_config(merge(base, sections))).run()
    assert summary.status == "complete"
    return out


def _tree(root: Path) -> dict[str, list[int]]:
    return {str(p.relative_to(root)): [p.stat().st_size, p.stat().st_mtime_ns] for p in sorted(root.rglob("*"))}


class SavedRuns:
    """Runs of :func:`small_run` made once a session and shared by every test and xdist worker that
    asks for the same settings: ``get(**sections)`` for a test that only reads the run,
    ``copy(dest, **sections)`` for one that writes into it (an export, traits.json). What
    ``get`` hands out must never change: each worker checks, at the session's end, that every
    file of the runs it used is as it was made."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.used: set[Path] = set()

    def get(self, **sections: object) -> Path:
        import hashlib
        import json

        from filelock import FileLock

        key = hashlib.sha256(json.dumps(sections, sort_keys=True, default=str).encode()).hexdigest()[:16]
        folder = self.root / key
        manifest = folder / "manifest.json"
        with FileLock(str(self.root / f"{key}.lock")):
            if not manifest.is_file():
                shutil.rmtree(folder, ignore_errors=True)  # a worker that died half-way
                small_run(folder / "run", **sections)
                manifest.write_text(json.dumps(_tree(folder / "run")))
        self.used.add(folder)
        return folder / "run"

    def copy(self, dest: Path, **sections: object) -> Path:
        shutil.copytree(self.get(**sections), dest)
        return dest

    def check_untouched(self) -> None:
        import json

        for folder in sorted(self.used):
            before, after = json.loads((folder / "manifest.json").read_text()), _tree(folder / "run")
            changed = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
            assert not changed, f"a test wrote into the shared run {folder / 'run'}: {changed[:5]}"


@pytest.fixture(scope="session")
def saved_runs(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SavedRuns]:
    """The session's :class:`SavedRuns`, in a folder all xdist workers of this run share."""
    base = tmp_path_factory.getbasetemp()
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "saved-runs"
    root.mkdir(exist_ok=True)
    runs = SavedRuns(root)
    yield runs
    runs.check_untouched()


def _run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Run ``agrisim ARGS`` in-process: (exit status, stdout, stderr)."""
    from agrisim.app.cli import main

    capsys.readouterr()
    try:
        code = main(args)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


class Frames:
    """A plugin object that keeps a copy of every capture's images, by frame name."""

    def __init__(self) -> None:
        self.images: dict[str, Frame] = {}

    @hookimpl
    def agrisim_capture(self, run, capture):  # noqa: ANN001 - pluggy passes what the hook names
        self.images[capture.frame] = capture.images.copy()


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]):  # noqa: ANN201 - returns the runner
    """``cli(args)`` runs ``agrisim ARGS`` in-process and returns (exit status, stdout, stderr)."""
    return lambda args: _run_cli(list(args), capsys)


@pytest.fixture
def frames() -> Frames:
    """A plugin object to register on an episode: it keeps a copy of every capture's images."""
    return Frames()


# ----------------------------------------------------------------- a leaf card (traits tests)

LEAF_LABELS = LabelTable([Label(0, "background", (0, 0, 0)), Label(1, "leaf", (0, 200, 0))])


def rotation_x(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def leaf_card(
    side: float, alpha: np.ndarray, tilt_deg: float = 0.0, at: tuple[float, float, float] = (0.0, 0.0, 0.1)
) -> Mesh:
    """A square card of ``side`` metres, textured with ``alpha`` (its RGBA's alpha), tilted about
    x by ``tilt_deg``, one leaf instance."""
    h, w = alpha.shape
    rgba = np.zeros((h, w, 4), np.uint8)
    rgba[..., 1] = 160
    rgba[..., 3] = alpha
    v = (np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]]) * side) @ rotation_x(tilt_deg).T
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    mat = Material("leaf", albedo=rgba, alpha_mode="MASK", label=1)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return Mesh("card", v + np.asarray(at), faces, [mat], np.zeros(2, np.int32), uv, np.array([1, 1], np.uint16))


class Kernel(NamedTuple):
    """A Dr.Jit kernel launched: its hash, whether it was compiled or read from disk (rather
    than found in this process's memory), and its size in operations."""

    hash: str
    fresh: bool
    operations: int


def kernels_launched(render: Callable[[], object]) -> list[Kernel]:
    """The Dr.Jit kernels ``render()`` launched."""
    import drjit as dr

    before = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()  # (drained)
        render()
        history = dr.kernel_history([dr.KernelType.JIT])
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, before)
    return [
        Kernel(k["hash"], not k["cache_hit"] or bool(k.get("cache_disk")), int(k["operation_count"])) for k in history
    ]
