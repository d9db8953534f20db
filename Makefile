# The one way to run things (STYLE habit 10): developers, CI and users run these targets.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
PIP := $(BIN)/python -m pip --disable-pip-version-check -q
DEMO_OUT ?= demo-out

.PHONY: demo test lint bench bench-bbw install install-test install-cholmod clean

$(BIN)/python:
	$(PY) -m venv $(VENV)

# Stamps re-run the install when pyproject.toml changes.
$(VENV)/.stamp-install: pyproject.toml | $(BIN)/python
	$(PIP) install -e ".[demo,weights,triangle]"
	@touch $@

$(VENV)/.stamp-test: pyproject.toml | $(BIN)/python
	$(PIP) install -e ".[test,bench,embree,triangle,tetgen,weights,demo]"
	@touch $@

# The system CHOLMOD (with OpenBLAS under it): the fastest sparse Cholesky, called
# through ctypes (src/stbs/weights/_cholmod.py) with solves on every core. Installed
# with apt-get when missing; without it the 'cholespy' and 'scipy' backends serve.
$(VENV)/.stamp-syslibs: | $(BIN)/python
	@ldconfig -p 2>/dev/null | grep -q 'libcholmod\.so' || { command -v apt-get >/dev/null && \
	  apt-get update -qq && apt-get install -y -qq libsuitesparse-dev libopenblas0-pthread; } || \
	  echo "note: no system CHOLMOD; BBW will use the cholespy backend (slower)"
	@touch $@

install: $(VENV)/.stamp-install $(VENV)/.stamp-syslibs
install-test: $(VENV)/.stamp-test $(VENV)/.stamp-syslibs

demo: install
	$(BIN)/stbs demo --out $(DEMO_OUT)

lint: install-test
	$(BIN)/ruff check src tests benchmarks

test: install-test lint
	$(BIN)/python -m pytest -q

# Eigen headers for the libigl C++ DQS peer (see docs/benchmarks.md); optional.
bench: install-test
	@test -f /usr/include/eigen3/Eigen/Core || { command -v apt-get >/dev/null && \
	  apt-get update -qq && apt-get install -y -qq libeigen3-dev; } || \
	  echo "note: no Eigen headers; the igl-dqs peer will be skipped"
	$(BIN)/stbs bench

# Optional fastest Cholesky: CHOLMOD built against Debian's SuiteSparse (bookworm has
# SuiteSparse 5.12; scikit-sparse 0.5 needs SuiteSparse 7).
install-cholmod: install-test
	command -v apt-get >/dev/null && apt-get update -qq && \
	  apt-get install -y -qq libsuitesparse-dev libopenblas0-pthread
	$(PIP) install "scikit-sparse>=0.4.12,<0.5"

bench-bbw: install-test
	$(BIN)/python benchmarks/bbw_vs_igl.py

clean:
	rm -rf $(VENV) build dist src/*.egg-info $(DEMO_OUT) .pytest_cache .ruff_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
