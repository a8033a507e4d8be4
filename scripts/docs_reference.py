"""The site's generated reference pages (run by mkdocs-gen-files at every `make docs`):

- ``reference/cli.md``: every subcommand's ``--help``, from agrisim's own argument parser, so
  the page and ``agrisim --help`` cannot disagree (tests/unit/test_docs.py checks them);
- ``reference/api/<package>.md``: each package of the core, one ``::: module`` a module, for
  mkdocstrings to render from the docstrings and type hints;
- ``plugins/kinds.md``: every kind of backend from the core's own table (``agrisim.kinds.KINDS``):
  its hook, setting, contract and factory, and the backends this installation registers.

mkdocstrings reads the package from ``scripts/docs-src/agrisim``, laid out here as it is installed
(``core/`` with ``plugins/`` and ``testing/`` inside it as ``agrisim.plugins`` and ``agrisim.testing``): links, rebuilt at every build.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import mkdocs_gen_files

sys.path.insert(0, str(Path(__file__).parent))
from griffe_roles import markdown  # noqa: E402 - beside this script, as mkdocs.yml names it

REPO = Path(__file__).resolve().parents[1]
#: the width the CLI page's help is formatted at (argparse reads $COLUMNS)
HELP_COLUMNS = 100

#: the packages of the Python API (the core's, and the apps' that a user's code calls), in the order the API pages list them, each with a line saying what it is
PACKAGES = {
    "agrisim": "The top level: configuration, the episode, the registry of backends and their contracts.",
    "agrisim.envs": "Gymnasium environments (`agrisim/PlantView-v0`).",
    "agrisim.plugins.apps.nextview": "Choosing views: coverage of the true surface, the voxel map, the policies.",
    "agrisim.plugins.apps.traits": "Plant traits: the truth from the mesh, the estimates from the views, their errors.",
    "agrisim.evaluation": "Accuracy against the true surface, views back-projected, the reconstruction session.",
    "agrisim.scene": "The scene: camera, lens, imager, meshes, plants, colours.",
    "agrisim.robot": "The arms: URDF, kinematics (Pinocchio), setpoints, trajectories, TF.",
    "agrisim.files": "The run directory's files: its layout, writer and readers, GLB, PNG/EXR, PLY, exports.",
    "agrisim.plugins.rooms.lab": "The lab room around the cell: room, clutter, textures.",
    "agrisim.testing": "The contract suite a backend is checked against, and perturbations for tests.",
    "agrisim.util": "Small helpers: caches on disk.",
}


def source_tree() -> None:
    """``scripts/docs-src/agrisim``: the installed package's layout, of links to the sources."""
    tree = REPO / "scripts" / "docs-src" / "agrisim"
    if tree.is_symlink() or tree.is_file():
        tree.unlink()
    tree.mkdir(parents=True, exist_ok=True)
    entries = {p.name: p for p in (REPO / "core").iterdir() if p.name != "__pycache__"}
    entries["plugins"] = REPO / "plugins"
    entries["testing"] = REPO / "testing"
    for old in tree.iterdir():  # (a link left by an older layout, e.g. a folder that moved)
        if old.name not in entries or old.readlink() != entries[old.name]:
            old.unlink()
    for name, target in entries.items():
        link = tree / name
        if not link.is_symlink():
            link.symlink_to(target)


def cli_page() -> str:
    from agrisim.app.arguments import build_parser

    os.environ["COLUMNS"] = str(HELP_COLUMNS)
    parser = build_parser()
    out = [
        "# Command line",
        "",
        "Generated from agrisim's argument parser at every build: each block is what "
        "`agrisim [COMMAND] --help` prints (at 100 columns).",
        "",
        "## agrisim",
        "",
        "```text",
        parser.format_help().rstrip(),
        "```",
    ]
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in sub.choices.items():
        out += ["", f"## agrisim {name}", "", "```text", command.format_help().rstrip(), "```"]
    return "\n".join(out) + "\n"


def modules(package: str) -> list[str]:
    """``package`` and its public modules, found in its source folder."""
    parts = package.split(".")
    root = (
        REPO / "plugins" / Path(*parts[2:]) if parts[:2] == ["agrisim", "plugins"] else REPO / "core" / Path(*parts[1:])
    )
    names = [] if package == "agrisim" else [package]
    names += [f"{package}.{p.stem}" for p in sorted(root.glob("*.py")) if not p.stem.startswith("_")]
    return names


def api_pages() -> None:
    index = [
        "# Python API",
        "",
        "Generated from the docstrings and type hints of the core (`agrisim`) and of the apps a user's code calls. Start with "
        "[the guide to the Python API](../../guides/python-api.md); a backend's contract is on "
        "[Backend kinds and hooks](../../plugins/kinds.md).",
        "",
        "| package | what it holds |",
        "|---|---|",
    ]
    for package, about in PACKAGES.items():
        slug = package.rpartition(".")[2]
        page = f"reference/api/{slug}.md"
        index.append(f"| [{package}]({slug}.md) | {about} |")
        body = [f"# {package}", "", about, ""]
        for name in modules(package):
            body += [f"::: {name}", ""]
        with mkdocs_gen_files.open(page, "w") as f:
            f.write("\n".join(body))
    with mkdocs_gen_files.open("reference/api/index.md", "w") as f:
        f.write("\n".join(index) + "\n")


def kinds_page() -> str:
    import inspect

    from agrisim import hookspecs
    from agrisim.kinds import KINDS
    from agrisim.registry import Registry, make_plugin_manager

    registry = Registry(make_plugin_manager())
    out = [
        "# Backend kinds and hooks",
        "",
        "Generated at every build from the core's table of kinds (`agrisim.kinds.KINDS`) and the "
        "hook specifications (`agrisim.hookspecs`); the backends listed are those registered where "
        "the site was built, as `agrisim plugins` lists them. [Writing a plugin](writing.md) shows "
        "one end to end.",
        "",
        "| kind | provider hook | chosen by | contract (ABC) | the core calls |",
        "|---|---|---|---|---|",
    ]
    for kind, info in KINDS.items():
        abc = f"[`{info.abc.__name__}`][{info.abc.__module__}.{info.abc.__name__}]" if info.abc else "any object"
        section = f"`[{info.section}] backend`" if info.section else "its name"
        hook = f"[`{info.hook}`][agrisim.hookspecs.{info.hook}]"
        out.append(f"| {kind} | {hook} | {section} | {abc} | `{info.factory}` |")
    for kind, info in KINDS.items():
        doc = inspect.getdoc(getattr(hookspecs, info.hook)) or ""
        doc = markdown(doc)  # the docstring's reST as the API pages show it
        out += ["", f"## {kind}", "", doc, ""]
        specs = registry.specs(kind)
        if specs:
            out += ["| built-in or installed | what it is |", "|---|---|"]
            out += [f"| `{name}` | {spec.description.replace('|', '/')} |" for name, spec in specs.items()]
    events = [
        n
        for n, f in inspect.getmembers(hookspecs, inspect.isfunction)
        if n.startswith("agrisim_run")
        or n in ("agrisim_trajectory", "agrisim_setpoint", "agrisim_capture", "agrisim_cloud")
    ]
    out += ["", "## Events", "", "Sinks and bridges implement these; return values are ignored.", ""]
    out += [f"- [`{name}`][agrisim.hookspecs.{name}]" for name in events]
    return "\n".join(out) + "\n"


with mkdocs_gen_files.open("plugins/kinds.md", "w") as f:
    f.write(kinds_page())
with mkdocs_gen_files.open("reference/cli.md", "w") as f:
    f.write(cli_page())
source_tree()
api_pages()
