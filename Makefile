# Two entry points, as the README says: `make run` and `make test`.
VENV ?= .venv
ARGS ?=

.PHONY: setup run test test-fast lint bench lock clean ros docs docs-serve wheel

setup:
	bash scripts/setup.sh

run: setup
	$(VENV)/bin/agrisim run $(ARGS)

# The suite: one worker a core (at most 4: each holds Open3D, Dr.Jit and a Ray cluster), a test
# module's tests together (their fixtures are built once), the heaviest modules handed out first
# (tests/conftest.py's MODULE_SECONDS); the slowest tests listed at the end.
test: setup
	bash scripts/test-deps.sh
	VENV=$(VENV) bash scripts/lint.sh
	$(VENV)/bin/python -m pytest -q -n auto --maxprocesses=4 --dist loadfile --no-loadscope-reorder --durations=15 tests

# The edit-test loop: the unit and contract tests and one small run, without the path tracer's
# module (Mitsuba's kernels take minutes to compile); no lint, no browser or ROS set-up. It does
# not replace `make test`, which CI runs.
test-fast: setup
	$(VENV)/bin/python -m pytest -q -n auto --maxprocesses=4 --dist loadfile --no-loadscope-reorder --durations=5 \
		--ignore=tests/unit/test_render_mitsuba.py tests/unit tests/contracts tests/e2e/test_episode.py

# Debian's ROS 1, for agrisim ros --ros 1 (make test installs it too)
ros:
	bash scripts/ros-deps.sh

# ruff's lint rules and formatting, and mypy on the core (also the first step of `make test`)
lint: setup
	VENV=$(VENV) bash scripts/lint.sh

# The documentation site (mkdocs.yml): built strictly into site/ (a broken link or reference
# fails), or served on loopback while you edit docs/
DOCS_ENV = NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true
docs: setup
	$(DOCS_ENV) $(VENV)/bin/mkdocs build --strict --site-dir site

docs-serve: setup
	$(DOCS_ENV) $(VENV)/bin/mkdocs serve --dev-addr 127.0.0.1:8000

# The sdist, and the wheel built from it, into dist/ (with the lock's setuptools: no download)
wheel: setup
	$(VENV)/bin/python -m build --no-isolation --outdir dist .

bench: setup
	$(VENV)/bin/python bench/robot_episode.py

# Re-resolve requirements.lock from pyproject.toml's ranges (newest versions that fit), with
# hashes, for every Python the project supports; then run `make test` before committing it.
# `make lock UPGRADE=` keeps every pin that still fits and only adds what is new (a dependency
# just added to pyproject.toml).
UPGRADE ?= --upgrade
lock: setup
	$(VENV)/bin/uv pip compile pyproject.toml --extra dev --extra helios --extra ros $(UPGRADE) --generate-hashes \
		--universal --python-version 3.10 --custom-compile-command "make lock" -o requirements.lock

clean:
	rm -rf $(VENV) runs .pytest_cache site dist
