#!/bin/bash
# A minimal agrisim for a GPU machine with no package index: the wheels of WHEELS (default .whl:
# Mitsuba and Dr.Jit slimmed by shared/tools/device-wheels.sh, plus pydantic, pygltflib, isal,
# pluggy and rich with their dependencies, for Python 3.12) and this tree's agrisim, with the entry
# points pip would register, so that `python3 -m agrisim render` finds its renderers. No Open3D,
# pybullet, Pinocchio or OMPL: enough to re-render saved runs and run bench/'s GPU scripts.
#   bash bench/device_install.sh [WHEELS [TARGET]]      (default TARGET: /tmp/site)
# WHEELS may also be a site-packages packed by bench/device_site.sh (a .tar.xz), unpacked as it is.
#   export PYTHONPATH=/tmp/site
set -euo pipefail
wheels=${1:-.whl}
target=${2:-/tmp/site}
if [[ "$wheels" == *.tar.xz ]]; then
  mkdir -p "$target" && tar -C "$target" -xJf "$wheels"
else
  python3 -m pip install -q --no-index --no-deps --no-compile --target "$target" "$wheels"/*.whl 2>/dev/null
fi
rm -rf "$target/agrisim" "$target"/agrisim-*.dist-info
cp -r core "$target/agrisim"
cp -r plugins "$target/agrisim/plugins"
python3 - "$target" <<'PY'
import pathlib
import sys
import tomllib

project = tomllib.loads(pathlib.Path("pyproject.toml").read_text())["project"]
info = pathlib.Path(sys.argv[1]) / f"agrisim-{project['version']}.dist-info"
info.mkdir()
(info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: agrisim\nVersion: {project['version']}\n")
groups = {"console_scripts": project["scripts"], **project["entry-points"]}
(info / "entry_points.txt").write_text(
    "".join(f"[{g}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) + "\n" for g, eps in groups.items())
)
PY
