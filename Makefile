# printapp: `make demo` runs the default design end to end, `make test` runs the tests.
# Both create .venv and install the project (with its dev extra) when needed, and try to
# install Debian's libllvm19 so that Mitsuba's fast llvm_ad_rgb variant works; `make test` also
# tries Debian's chromium, prusa-slicer and admesh, which tests run beside printapp.

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.printapp-installed

.PHONY: demo test test-fast lint format bench llvm chromium peers clean

demo: $(STAMP) llvm
	$(BIN)/printapp demo

# Spread over the cores (pytest-xdist): most tests are single-threaded numpy and numba.
test: $(STAMP) llvm chromium peers
	$(BIN)/python -m pytest -q -n auto --dist loadgroup

# The edit-test loop: everything but the end-to-end and heavy tests (marked slow).
test-fast: $(STAMP) llvm
	$(BIN)/python -m pytest -q -n auto --dist loadgroup -m "not slow"

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: $(STAMP)
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

bench: $(STAMP) llvm peers
	@# pyfastnoisesimd (the noise peer) builds only without build isolation, after cython.
	$(BIN)/python -c "import pyfastnoisesimd" 2>/dev/null || \
		{ $(BIN)/python -m pip install --quiet cython setuptools wheel && \
		  $(BIN)/python -m pip install --quiet --no-build-isolation pyfastnoisesimd; } || \
		echo "warning: pyfastnoisesimd did not install; bench noise runs without the Perlin peer" >&2
	$(BIN)/python -c "import rlic" 2>/dev/null || $(BIN)/python -m pip install --quiet rlic || \
		echo "warning: rlic did not install; bench lic runs without its peer" >&2
	$(BIN)/python -c "import embreex" 2>/dev/null || $(BIN)/python -m pip install --quiet embreex || \
		echo "warning: embreex did not install; bench brdf runs without its Embree peer" >&2
	$(BIN)/python -c "import miepython" 2>/dev/null || $(BIN)/python -m pip install --quiet miepython || \
		echo "warning: miepython did not install; bench mie runs without its peer" >&2
	@sh scripts/apt-install.sh "command -v blender" "bench mesh and commands run without their Blender peer" blender
	$(BIN)/printapp bench -o bench-out

llvm:
	@sh scripts/install-llvm.sh

chromium:
	@sh scripts/install-chromium.sh

# PrusaSlicer and ADMesh, which tests run beside printapp (skipped where they cannot install).
peers:
	@sh scripts/install-peers.sh

$(BIN)/python:
	@sh scripts/make-venv.sh "$(PYTHON)" "$(VENV)"

$(STAMP): pyproject.toml | $(BIN)/python llvm
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	@# Compile and cache every kernel now, so that the first demo runs as fast as the second.
	$(BIN)/printapp warmup --quiet
	@touch $(STAMP)

clean:
	rm -rf $(VENV) printapp-demo bench-out build *.egg-info .pytest_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
