"""The architecture holds: no import cycle among agrisim's modules (counting imports made only
for type hints or inside functions), and the contracts and plugin discovery stay light."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGES = {"agrisim": REPO / "core", "agrisim.testing": REPO / "testing", "agrisim.plugins": REPO / "plugins"}
HEAVY = ("open3d", "pybullet", "pinocchio", "coal", "ompl", "rerun", "ray")


def modules() -> dict[str, Path]:
    """Every agrisim module by dotted name."""
    out = {}
    for package, root in PACKAGES.items():
        for path in root.rglob("*.py"):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([package, *parts])] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the agrisim modules it imports anywhere in its source."""
    mods = modules()
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        deps: set[str] = set()
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                # relative imports (``from .recording import X``, ``from . import x``) resolved
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    base = ".".join(anchor + ([node.module] if node.module else []))
                if not base:
                    continue
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    deps.add(full if full in mods else base)
            elif isinstance(node, ast.Import):
                deps |= {alias.name for alias in node.names}
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_import_cycles() -> None:
    graph = import_graph()
    assert len(graph) > 60  # the walk found the packages
    assert cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle() -> None:
    graph = import_graph()
    graph["agrisim.scene.camera"] = graph["agrisim.scene.camera"] | {"agrisim.interfaces"}  # the old cycle
    assert any({"agrisim.interfaces", "agrisim.scene.camera"} <= set(c) for c in cycles(graph))


def _absolute(package: str, node: ast.ImportFrom) -> str:
    """The module an ``ImportFrom`` in ``package`` names, relative imports resolved."""
    if not node.level:
        return node.module or ""
    anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
    return ".".join(anchor + ([node.module] if node.module else []))


def private_reach_ins(name: str, source: str, mods: dict[str, Path]) -> list[str]:
    """The private names of other agrisim modules that module ``name`` (of ``source``) uses:
    imported (``from agrisim.plugins.apps.compare import _probe``) or reached through an imported
    module (``compare._probe``). A name with a leading underscore is its module's own."""
    package = name if mods.get(name, Path()).name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(source)
    found: list[str] = []
    aliases: dict[str, str] = {}  # a local name -> the agrisim module it is bound to
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = _absolute(package, node)
            for alias in node.names:
                full = f"{base}.{alias.name}"
                if full in mods:
                    aliases[alias.asname or alias.name] = full
                elif base in mods and base != name and alias.name.startswith("_") and not alias.name.startswith("__"):
                    found.append(full)
        elif isinstance(node, ast.Import):
            aliases |= {alias.asname: alias.name for alias in node.names if alias.asname and alias.name in mods}
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            module = aliases[node.value.id]
            if module != name and node.attr.startswith("_") and not node.attr.startswith("__"):
                found.append(f"{module}.{node.attr}")
    return found


def test_no_module_uses_another_modules_private_name() -> None:
    mods = modules()
    reach_ins = {name: private_reach_ins(name, path.read_text(), mods) for name, path in mods.items()}
    assert {name: found for name, found in reach_ins.items() if found} == {}


@pytest.mark.parametrize(
    "source",
    [
        "from agrisim.plugins.apps.compare_plan import check_same_settings, _plan",
        "from .compare_plan import _plan",
        "from agrisim.plugins.apps import compare_plan as plans\nplans._plan()",
    ],
)
def test_the_private_name_check_catches_a_reach_in(source: str) -> None:
    assert private_reach_ins("agrisim.plugins.apps.sweep", source, modules()) == [
        "agrisim.plugins.apps.compare_plan._plan"
    ]
    assert private_reach_ins("agrisim.plugins.apps.compare_plan", "_plan = 1\n_plan", modules()) == []  # its own


def _loaded_after(code: str) -> set[str]:
    """Modules a fresh interpreter has loaded after running ``code``."""
    probe = f"import sys, io, contextlib\n{code}\nprint(' '.join(sorted(sys.modules)))"
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return set(proc.stdout.split())


@pytest.mark.parametrize(
    "code",
    [
        "import agrisim.interfaces",
        "import agrisim.hookspecs, agrisim.kinds, agrisim.capabilities, agrisim.records",
        "from agrisim.app.cli import main\nwith contextlib.redirect_stdout(io.StringIO()): main(['plugins', '--options'])",
    ],
    ids=["interfaces", "contracts", "agrisim-plugins"],
)
def test_contracts_and_discovery_import_no_heavy_library(code: str) -> None:
    loaded = _loaded_after(code)
    assert not {m for m in loaded if m.split(".")[0] in HEAVY}
    if "plugins" not in code:  # the contracts do not load the configuration or the robot either
        assert not {"agrisim.config", "agrisim.robot.urdf", "agrisim.robot.cell", "agrisim.episode"} & loaded


#: the file formats' libraries of the exporters (plugins/exporters), which the core must not load
FORMAT_LIBRARIES = ("rosbags", "pycocotools")


def core_modules() -> list[str]:
    """Every module of the core and its test harness (agrisim, agrisim.testing; not
    agrisim.plugins), but ``agrisim.__main__``."""
    return sorted(name for name in modules() if not name.startswith("agrisim.plugins") and name != "agrisim.__main__")


def test_the_core_imports_no_plugin() -> None:
    """Backends, exporters included, are plugins reached through the registry: no core module
    imports one, at its top or inside a function."""
    graph = import_graph()
    core = core_modules()
    assert len(core) > 50 and "agrisim.files.rundir" in core
    reached = {name: sorted(d for d in graph[name] if d.startswith("agrisim.plugins")) for name in core}
    assert {name: deps for name, deps in reached.items() if deps} == {}


def test_the_plugin_check_catches_a_core_module_importing_a_plugin() -> None:
    graph = import_graph()
    graph["agrisim.files.rundir"] = graph["agrisim.files.rundir"] | {"agrisim.plugins.exporters.nerfstudio"}
    assert [d for d in graph["agrisim.files.rundir"] if d.startswith("agrisim.plugins")]


@pytest.mark.parametrize(
    "code",
    [
        "import agrisim, agrisim.app.cli",
        "import importlib\nfor name in {core}:\n    importlib.import_module(name)",
        "from agrisim.app.cli import main\nwith contextlib.redirect_stdout(io.StringIO()): main(['plugins', '--options'])",
    ],
    ids=["cli", "every-core-module", "agrisim-plugins"],
)
def test_the_core_loads_no_export_format_library(code: str) -> None:
    """The exporters' format libraries (the ROS 2 bag's rosbags, COCO's pycocotools) load only
    when an export runs: not with the core, every module of it, nor while ``agrisim plugins``
    lists the exporters."""
    loaded = _loaded_after(code.format(core=core_modules()))
    assert {m for m in loaded if m.split(".")[0] in FORMAT_LIBRARIES} == set()
    if "{core}" in code:
        assert set(core_modules()) <= loaded  # the probe imported them all


def test_the_format_library_check_sees_a_library_loaded() -> None:
    loaded = _loaded_after("import agrisim.app.cli\nimport rosbags.typesys")
    assert {m for m in loaded if m.split(".")[0] in FORMAT_LIBRARIES}


def _architecture_block() -> str:
    page = (REPO / "docs" / "concepts" / "architecture.md").read_text()
    section = page[page.index("# Architecture") :]
    start = section.index("```\n") + 4
    return section[start : section.index("```", start)]


def test_the_architecture_page_matches_the_tree() -> None:
    """Every folder and top-level module the architecture page's map names exists, and every one that
    exists is in the map: core's modules and subpackages, each plugin kind and backend package."""
    block = _architecture_block()
    listed: dict[str, set[str]] = {"core": set(), "plugins": set(), "tests": set()}
    top = None
    for line in block.splitlines():
        if line and not line.startswith(" "):
            top = line.split()[0].rstrip("/")
        elif top in listed and line.startswith("  ") and not line.startswith("   "):
            listed[top].add(line.split()[0])
    core = {p.name for p in (REPO / "core").glob("*.py") if p.name != "__init__.py" and p.name != "__main__.py"}
    core |= {f"{p.name}/" for p in (REPO / "core").iterdir() if (p / "__init__.py").exists()}
    assert listed["core"] == core, (
        f"the map lists {sorted(listed['core'] - core)}, misses {sorted(core - listed['core'])}"
    )
    kinds = {f"{p.name}/" for p in (REPO / "plugins").iterdir() if (p / "__init__.py").exists()}
    assert listed["plugins"] == kinds
    assert listed["tests"] == {
        f"{p.name}/" for p in (REPO / "tests").iterdir() if p.is_dir() and any(p.glob("test_*.py"))
    }
    # every backend package (a folder of several files) is named in the map
    for kind in (REPO / "plugins").iterdir():
        for pkg in kind.iterdir() if kind.is_dir() else ():
            if (pkg / "__init__.py").exists():
                assert f"{pkg.name}/" in block, (
                    f"plugins/{kind.name}/{pkg.name}/ is missing from the architecture page's map"
                )


def test_no_renderer_imports_open3d() -> None:
    """Renderers trace with Dr.Jit: no module under plugins/render imports Open3D (it stays for
    reconstruction and accuracy), and rendering a view with raycast and with mitsuba loads it
    nowhere."""
    for name, path in modules().items():
        if name.startswith("agrisim.plugins.render"):
            for node in ast.walk(ast.parse(path.read_text())):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
                if isinstance(node, ast.ImportFrom):
                    names = [node.module or ""]
                assert not [n for n in names if n.split(".")[0] == "open3d"], name
    code = (
        "import numpy as np\n"
        "from agrisim.config import RenderConfig\n"
        "from agrisim.scene.camera import from_fov\n"
        "from agrisim.scene.model import LabelTable, Light, Material, Mesh, Scene\n"
        "from agrisim.plugins.render.raycast import RaycastOptions\n"
        "from agrisim.plugins.render.raycast.renderer import RaycastRenderer\n"
        "from agrisim.plugins.render.mitsuba.options import MitsubaOptions\n"
        "from agrisim.plugins.render.mitsuba.renderer import MitsubaRenderer\n"
        "quad = Mesh('floor', np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float),"
        " np.array([[0, 1, 2], [0, 2, 3]]), [Material('m')], np.zeros(2, np.int32))\n"
        "scene = Scene([quad], [Light('l', 'point', np.array([0.0, 0, 2]), np.array([0.0, 0, -1]))], LabelTable())\n"
        "T = np.diag([1.0, -1.0, -1.0, 1.0]); T[2, 3] = 2.0\n"
        "cam = from_fov(60.0, 32, 24)\n"
        "for r in (RaycastRenderer(scene, None, RenderConfig(hide_robots=True), RaycastOptions()),"
        " MitsubaRenderer(scene, None, RenderConfig(hide_robots=True), MitsubaOptions(spp=1, denoise='off'))):\n"
        "    assert (r.render(cam, T, {}).depth > 0).mean() > 0.5\n"
    )
    assert "open3d" not in {m.split(".")[0] for m in _loaded_after(code)}


def test_the_public_api_lists_every_name_it_serves() -> None:
    """``agrisim.__all__`` is spelt out for linters: it must hold every lazily served name, and
    each name in it must resolve."""
    import agrisim

    assert set(agrisim._LAZY) <= set(agrisim.__all__)
    for name in agrisim.__all__:
        assert getattr(agrisim, name) is not None, name


# ---------------------------------------------------------------- layers, sizes


def page_layers() -> list[tuple[str, set[str]]]:
    """The layers the architecture page lists, from the bottom up: (name, the core's top-level
    modules and folders in it, without ``.py`` or ``/``)."""
    page = (REPO / "docs" / "concepts" / "architecture.md").read_text()
    section = page[page.index("## Layers") : page.index("## The tree")]
    layers = []
    for line in section.splitlines():
        found = re.match(r"\d+\. \*\*(.+?)\*\*: (.+)$", line)
        if found:
            layers.append((found.group(1), {n.rstrip("/") for n in re.findall(r"`([^`]+)`", found.group(2))}))
    return layers


def layer_of(module: str, layers: list[tuple[str, set[str]]]) -> int:
    """The index of ``module``'s layer (``agrisim.testing`` is the harness's folder, ``testing``)."""
    parts = module.split(".")
    key = parts[1] if len(parts) > 1 else "__init__"
    for i, (_, names) in enumerate(layers):
        if key in names:
            return i
    raise AssertionError(f"{module} is in no layer of the architecture page")


def upward_imports(graph: dict[str, set[str]], layers: list[tuple[str, set[str]]]) -> list[str]:
    """Every import in the core that reaches a layer above the importer's."""
    core = set(core_modules()) | {"agrisim.__main__"}
    return sorted(
        f"{a} -> {d}" for a in core for d in graph[a] if d in core and layer_of(d, layers) > layer_of(a, layers)
    )


def test_the_cores_imports_run_only_downward() -> None:
    """Each core module imports only from its own layer and those below it, as the architecture
    page draws them (type hints and imports inside functions included), and every core module
    is in a layer."""
    layers = page_layers()
    assert [name for name, _ in layers][:2] == ["base", "scene model"] and len(layers) >= 8
    assert upward_imports(import_graph(), layers) == []


def test_the_layer_check_catches_an_upward_import() -> None:
    graph = import_graph()
    graph["agrisim.scene.model"] = graph["agrisim.scene.model"] | {"agrisim.registry"}
    assert upward_imports(graph, page_layers()) == ["agrisim.scene.model -> agrisim.registry"]


#: the most lines a module may hold (a longer one does more than the one job its name says)
MODULE_LINES = 600
#: the most lines of Python core/ may hold: what the mission calls a small core
CORE_LINES = 7_000


def test_no_module_is_over_600_lines() -> None:
    long = {
        str(p.relative_to(REPO)): n for p in modules().values() if (n := len(p.read_text().splitlines())) > MODULE_LINES
    }
    assert long == {}


def test_the_core_stays_within_its_size() -> None:
    lines = sum(len(p.read_text().splitlines()) for p in (REPO / "core").rglob("*.py"))
    assert lines <= CORE_LINES, f"core/ holds {lines} lines of Python, more than {CORE_LINES}"


def test_the_modules_the_scheduler_hands_out_first_exist() -> None:
    """tests/conftest.py's MODULE_SECONDS orders the suite: a renamed module would silently fall
    back to its collection order."""
    from conftest import MODULE_SECONDS

    missing = [name for name in MODULE_SECONDS if not (REPO / name).is_file()]
    assert not missing, missing
