# Quick start (see README.md):
#   make demo   -- set up a virtual environment and run the main job
#   make test   -- set up and run the whole test suite, lint and type checks
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
export OPENBLAS_NUM_THREADS := 1
export MPLBACKEND := Agg

.PHONY: demo test setup setup-test lint typecheck bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed pyproject.toml
	$(PY) -m pip install --quiet -e ".[test]"
	touch $@

setup: $(VENV)/.installed
setup-test: $(VENV)/.installed-test

demo: setup
	$(VENV)/bin/gracenav demo --out out/demo

lint: setup-test
	$(PY) -m ruff check src tests bench tools examples
	$(PY) -m ruff format --check src tests bench tools examples

typecheck: setup-test
	$(PY) -m mypy

test: lint typecheck
	$(PY) -m pytest -q

bench: setup-test
	for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache
