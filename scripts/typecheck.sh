#!/usr/bin/env bash
# Type-checks the agrisim package (core/, and plugins/ as agrisim.plugins) with mypy; the configuration is pyproject.toml's
# [tool.mypy]. Extra arguments go to mypy. MYPY names the mypy command (default: the one the lock
# installs into the venv); the venv's Python is always the one whose packages mypy reads.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=${VENV:-.venv}
MYPY=${MYPY:-"$VENV/bin/python -m mypy"}

# The package is agrisim but its folders are core/ and plugins/ (setuptools' package-dir). mypy
# maps a module to a folder of the same name on its search path and cannot follow the editable
# install's import hook, so it reads them through .typecheck/agrisim (pyproject's mypy_path
# points here): links to core/'s entries, plugins/ and testing/, laid out as the package is installed.
rm -rf .typecheck/agrisim
mkdir -p .typecheck/agrisim
for entry in core/*; do
  [ "$(basename "$entry")" = __pycache__ ] || ln -s "../../$entry" .typecheck/agrisim/
done
ln -s ../../plugins .typecheck/agrisim/plugins
ln -s ../../testing .typecheck/agrisim/testing

# MYPY is a command line ("python -m mypy"): splitting it into words is intended. Errors name
# the files as mypy read them, through the link; they are shown under core/, where they are edited
# (pipefail keeps mypy's exit status).
# shellcheck disable=SC2086
$MYPY --python-executable "$VENV/bin/python" "$@" | sed 's#^\.typecheck/agrisim/plugins/#plugins/#; s#^\.typecheck/agrisim/testing/#testing/#; s#^\.typecheck/agrisim/#core/#'
