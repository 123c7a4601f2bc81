# The two commands: `make demo` runs the main job, `make test` runs the tests.
# Each creates .venv and installs the project into it when needed.
# PYTHON: any CPython 3.11-3.13 (`make test PYTHON=python3.13 VENV=.venv313` keeps one venv per interpreter).
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
WORKDIR ?= demo
# pytest processes of `make test` (pytest-xdist; each test file runs whole in one of them, so a
# file's module fixtures are built once): one per core of the 2-core machines CI runs on
TEST_WORKERS ?= 2

export PREFECT_SERVER_ANALYTICS_ENABLED := false
export DO_NOT_TRACK := 1

.PHONY: demo test fuzz venv lint bench clean

# A PYTHON given on the command line must be the interpreter of an existing VENV.
ifeq ($(origin PYTHON),command line)
VENV_MISMATCH := $(shell test -x $(PY) && test "$$($(PY) -c 'import sys; print(sys.version_info[:2])')" != "$$($(PYTHON) -c 'import sys; print(sys.version_info[:2])')" && echo yes)
ifeq ($(VENV_MISMATCH),yes)
$(error $(VENV) was made with another Python than $(PYTHON): pass e.g. VENV=.venv313 for one venv per interpreter, or remove $(VENV))
endif
endif

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/stormlane demo --out $(WORKDIR)
	@echo "the stormlane command: $(VENV)/bin/stormlane (or run '. $(VENV)/bin/activate' to put it on PATH)"

# The browser test needs headless Chromium: install Debian's package when it is missing
# (as root, or through sudo), and make that test fail rather than skip when it is absent.
test: $(STAMP)
	command -v chromium >/dev/null 2>&1 || { SUDO=$$(test "$$(id -u)" -eq 0 || echo sudo); \
	  $$SUDO apt-get update -qq && $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium; }
	$(VENV)/bin/lint-imports
	STORMLANE_REQUIRE_BROWSER=1 $(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# The property tests (Hypothesis) with new random examples each run (`make test` runs fixed ones).
fuzz: $(STAMP)
	$(PY) -m pytest -q --hypothesis-profile=explore $$(grep -l "@given" tests/test_*.py)

# Every benchmark (bench/*.py through bench/_harness.py), within 30 min on 2 cores: writes
# bench/results.json, README.md's benchmark table and docs/benchmarks.md.
bench: $(STAMP)
	$(PY) -m bench

clean:
	rm -rf $(VENV) $(WORKDIR) .pytest_cache
