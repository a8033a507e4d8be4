# Two entry points, as the README says: `make run` and `make test`.
VENV ?= .venv
ARGS ?=

.PHONY: setup run test bench clean

setup:
	bash scripts/setup.sh

run: setup
	$(VENV)/bin/agrisim run $(ARGS)

test: setup
	$(VENV)/bin/python -m pytest -q tests

bench: setup
	$(VENV)/bin/python bench/robot_episode.py

clean:
	rm -rf $(VENV) runs .pytest_cache
