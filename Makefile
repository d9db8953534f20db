# The one way to run things (STYLE habit 10): developers, CI and users run these targets.
# Needs only Python 3.11, git, make and Node (Debian bookworm); the rest is installed
# here: the Python packages into .venv, the viewer's npm packages into viewer/, and the
# system libraries and Chromium with apt-get when missing.
# make test runs the fuzz suite's short profile, make fuzz its long one (about 10 minutes).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
PIP := $(BIN)/python -m pip --disable-pip-version-check -q
DEMO_OUT ?= demo-out
# The PyTorch release the test environment takes in its CPU build (docs/dependencies.md).
TORCH_CPU ?= 2.13.0
# The viewer's bundles (three.js and viewer/src, by esbuild; built, never committed): the
# page's and the peer page's of stbs bench --viewer, in src/stbs/viewer/static/. Declared
# once, in viewer/bundles.json, and built by viewer/build.mjs, which npm run build and
# setup.py's build hook call too.
BUNDLES := $(shell node viewer/build.mjs --outputs)
ifeq ($(strip $(BUNDLES)),)
$(error the Makefile needs Node: node viewer/build.mjs --outputs named no bundles)
endif

.PHONY: demo test pytest fuzz wheel-check lint bench bench-igl bench-bbw install install-test clean

$(BIN)/python:
	$(PY) -m venv $(VENV)

# Stamps re-run the install when pyproject.toml changes. The viewer's bundle is built
# first, so that the editable install and the wheel ship it.
$(VENV)/.stamp-install: pyproject.toml | $(BIN)/python $(BUNDLES)
	$(PIP) install -e ".[demo,weights,triangle]"
	@touch $@

# PyTorch pinned first to its CPU build (TORCH_CPU; pip takes it from a local wheel
# folder or the index pip is given), so that the torch extra's range installs nothing more.
$(VENV)/.stamp-test: pyproject.toml | $(BIN)/python $(BUNDLES)
	$(PIP) install "torch==$(TORCH_CPU)"
	$(PIP) install -e ".[test,bench,embree,triangle,tetgen,weights,demo,batch,usd,fbx,torch,jax]"
	@touch $@

# npm packages from the committed lock file (viewer/package-lock.json), then the bundle.
# --ignore-scripts: esbuild's install script only checks its binary, which npm installs as
# esbuild's optional dependency for this platform.
viewer/node_modules/.package-lock.json: viewer/package.json viewer/package-lock.json
	npm ci --prefix viewer --no-audit --no-fund --ignore-scripts
	@touch $@

# Every bundle at once (a grouped target): esbuild takes well under a second for both.
$(BUNDLES) &: viewer/node_modules/.package-lock.json viewer/build.mjs viewer/bundles.json \
  $(shell find viewer/src -type f)
	node viewer/build.mjs

# The Khronos glTF validator (npm gltf-validator, run under Node by the glTF tests),
# from its committed lock file.
tests/node/node_modules/.package-lock.json: tests/node/package.json tests/node/package-lock.json
	npm ci --prefix tests/node --no-audit --no-fund
	@touch $@

# Chromium for the viewer's browser tests (Playwright drives it; it never downloads a
# browser of its own), from apt when missing.
$(VENV)/.stamp-chromium: | $(BIN)/python
	@test -x /usr/bin/chromium || { command -v apt-get >/dev/null && apt-get update -qq && \
	  apt-get install -y -qq chromium; } || \
	  echo "note: no /usr/bin/chromium; the viewer's browser tests will fail"
	@touch $@

# The system CHOLMOD (with OpenBLAS under it): the fastest sparse Cholesky, called
# through ctypes (src/stbs/weights/_cholmod.py) with solves on every core. Installed
# with apt-get when missing; without it the 'cholespy' and 'scipy' backends serve.
$(VENV)/.stamp-syslibs: | $(BIN)/python
	@ldconfig -p 2>/dev/null | grep -q 'libcholmod\.so' || { command -v apt-get >/dev/null && \
	  apt-get update -qq && apt-get install -y -qq libsuitesparse-dev libopenblas0-pthread; } || \
	  echo "note: no system CHOLMOD; BBW will use the cholespy backend (slower)"
	@touch $@

# For benchmarks/skinning_vs_igl.py's C++ peer (libigl's igl::dqs): a C++ compiler and
# Eigen's headers; libigl's headers come from the user (LIBIGL_INCLUDE, a checkout).
$(VENV)/.stamp-cxx: | $(BIN)/python
	@{ command -v g++ >/dev/null && test -f /usr/include/eigen3/Eigen/Core; } || \
	  { command -v apt-get >/dev/null && apt-get update -qq && \
	    apt-get install -y -qq g++ libeigen3-dev; } || \
	  echo "note: no g++ or Eigen headers; the igl-dqs peer will be skipped"
	@touch $@

install: $(VENV)/.stamp-install $(VENV)/.stamp-syslibs $(BUNDLES)
install-test: $(VENV)/.stamp-test $(VENV)/.stamp-syslibs $(VENV)/.stamp-chromium $(BUNDLES) \
  tests/node/node_modules/.package-lock.json

demo: install
	$(BIN)/stbs demo --out $(DEMO_OUT)

lint: install-test
	$(BIN)/ruff check src tests benchmarks

# The page's unit tests (node --test viewer/test), then the whole suite, slow tests
# included, with the docstring and README.md examples (pyproject.toml: testpaths,
# --doctest-modules); the suite holds wheel-check's test of the package as users get it.
# Quick loop: .venv/bin/python -m pytest -m "not slow" (docs/dev/testing.md).
test: install-test lint
	node --test viewer/test/
	$(BIN)/python -m pytest -q --durations=20

pytest: install-test
	$(BIN)/python -m pytest -q --durations=20

# The fuzz suite's long profile (docs/dev/testing.md, "Fuzzing"): mutated files through
# the real commands for STBS_FUZZ_SECONDS seconds (default 600); it must find nothing.
fuzz: install-test
	STBS_FUZZ_SECONDS=$${STBS_FUZZ_SECONDS:-600} $(BIN)/python -m pytest -q -s tests/fuzz

# The package as users get it (tests/test_packaging_install.py; docs/dev/packaging.md):
# from a clean clone of HEAD, the wheel (as pip install . builds it), the sdist, and a
# wheel built without npm (it must warn); the wheel installed with its dependencies into
# a fresh virtual environment (every file git has under src/stbs and the viewer's
# bundles; stbs --help, --version, bench --sizes 10k --no-peers, demo --quick with the
# demo extra, from a folder outside the source tree), the sdist installed by pip without
# npm into another; in both, stbs view's page opened in Chromium until it is ready.
# make test runs it with the rest of the suite.
wheel-check: install-test
	$(BIN)/python -m pytest -q -p no:cacheprovider tests/test_packaging_install.py

bench: install-test
	$(BIN)/stbs bench

# The libigl peers (benchmarks/README.md): igl.lbs_matrix and the C++ igl::dqs beside
# stbs bench's rows; the weights beside igl.bbw.
bench-igl: install-test $(VENV)/.stamp-cxx
	$(BIN)/python benchmarks/skinning_vs_igl.py

bench-bbw: install-test
	$(BIN)/python benchmarks/bbw_vs_igl.py

clean:
	rm -rf $(VENV) build dist src/*.egg-info $(DEMO_OUT) .pytest_cache .ruff_cache \
	  viewer/node_modules tests/node/node_modules $(BUNDLES)
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
