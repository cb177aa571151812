# Quick start (see README.md):
#   make demo   -- set up a virtual environment and run the main job
#   make test   -- set up and run the whole test suite, lint and type checks
#   make test-fast -- lint and the suite without the tests marked slow (under 2 minutes)
#   make docs   -- build the documentation site into site/
# Installs take every version from requirements/lock.txt (see `make lock`).
# `make test VENV=.venv-latest CONSTRAINTS=` runs the suite on the newest versions instead.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
CONSTRAINTS ?= requirements/lock.txt
export OPENBLAS_NUM_THREADS := 1
export MPLBACKEND := Agg
export NO_MKDOCS_2_WARNING := 1
# The lock also pins what pip builds the project with (setuptools in the isolated build).
ifneq ($(CONSTRAINTS),)
export PIP_CONSTRAINT := $(abspath $(CONSTRAINTS))
endif

.PHONY: demo test test-fast setup setup-test lint typecheck docs bench lock clean

$(VENV)/.installed: pyproject.toml $(CONSTRAINTS)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip setuptools
	$(PY) -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed pyproject.toml $(CONSTRAINTS)
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

# The site, strictly: a broken link or a missing API reference fails the build.
docs: setup-test
	$(PY) -m mkdocs build --strict --site-dir site

test: lint typecheck docs
	$(PY) -m pytest -q

# While developing: the tests marked slow (pytest -m slow) are left out.
test-fast: lint
	$(PY) -m pytest -q -m "not slow"

# bench_scale.py (100 m maps, needs > 8 GiB for the open hall) runs on its own.
bench: setup-test
	$(PY) -m pip install --quiet -e ".[bench]"
	for b in bench/bench_*.py; do \
	  case $$b in *bench_scale.py) continue;; esac; \
	  echo "== $$b"; $(PY) $$b || exit 1; done

# Re-resolve every dependency (with all extras) to the newest versions the package
# index serves, in a throwaway environment, and write them to requirements/lock.txt.
lock:
	rm -rf .venv-lock
	env -u PIP_CONSTRAINT $(PYTHON) -m venv .venv-lock
	env -u PIP_CONSTRAINT .venv-lock/bin/python -m pip install --quiet --upgrade pip setuptools
	env -u PIP_CONSTRAINT .venv-lock/bin/python -m pip install --quiet ".[test,docs,mujoco,bench,log,ros]"
	mkdir -p requirements
	{ echo "# Every package the Makefile installs, pinned; regenerate with 'make lock'."; \
	  echo "# Resolved on $$(date -u +%Y-%m-%d) with $$(.venv-lock/bin/python --version)."; \
	  .venv-lock/bin/python -m pip freeze --all | grep -v '^gracenav' | LC_ALL=C sort -f; \
	} > requirements/lock.txt
	rm -rf .venv-lock

clean:
	rm -rf $(VENV) .venv-latest .venv-lock out site .pytest_cache .mypy_cache .ruff_cache
