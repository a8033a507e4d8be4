#!/usr/bin/env bash
# The static checks of `make test`, before the suite: ruff's lint rules and its formatting over
# every Python file of the project, and mypy over the package, core and plugins (scripts/typecheck.sh). Their
# configuration is in pyproject.toml. `ruff format .` and `ruff check --fix .` repair most of
# what the first two find.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv}

"$VENV/bin/ruff" check --quiet .
"$VENV/bin/ruff" format --check --quiet . || {
  echo "lint: files above are not formatted; run: $VENV/bin/ruff format ." >&2
  exit 1
}
VENV="$VENV" bash scripts/typecheck.sh
