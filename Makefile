# Two entry points, each of which sets everything up first (idempotent):
#   make demo   -> venv + install + `rfsdf demo`
#   make demo-sar -> the same on GeRaF's scanned set-up (`rfsdf demo --radar sar-77g`)
#   make test   -> venv + install + the test suite (which builds the docs too)
#   make docs   -> the documentation site in site/
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

BROWSER := $(VENV)/.browser

.PHONY: setup demo demo-sar test docs bench

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch pinned: the 2.13.0 CPU build is what is available offline; unpinned pulls CUDA.
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e ".[test]"
	touch $(STAMP)

# Headless Chromium for the report's browser test, from Debian's packages (needs root or
# sudo); where it cannot be installed the test skips and says why.
$(BROWSER): $(STAMP)
	command -v chromium >/dev/null 2>&1 || { SUDO=$$( [ "$$(id -u)" = 0 ] || echo "sudo -n" ); \
	  $$SUDO apt-get install -y -q chromium >/dev/null 2>&1 || \
	  { $$SUDO apt-get update -q >/dev/null 2>&1 && $$SUDO apt-get install -y -q chromium >/dev/null 2>&1; } || \
	  echo "could not install chromium: the browser test will skip"; }
	touch $(BROWSER)

setup: $(STAMP)

demo: $(STAMP)
	$(BIN)/rfsdf demo

demo-sar: $(STAMP)
	$(BIN)/rfsdf demo --radar sar-77g --out rfsdf-demo-sar

# One pytest worker a core (pytest-xdist), each at one thread (RFSDF_TEST_THREADS=N: N): numba's
# and OpenMP's pools would otherwise take every core in every worker, and their waiting threads
# spin. The files with a long module fixture go whole to one worker (tests/conftest.py).
TEST_THREADS := $(or $(RFSDF_TEST_THREADS),1)
test: $(STAMP) $(BROWSER)
	NUMBA_NUM_THREADS=$(TEST_THREADS) OMP_NUM_THREADS=$(TEST_THREADS) OPENBLAS_NUM_THREADS=$(TEST_THREADS) \
	  MKL_NUM_THREADS=$(TEST_THREADS) $(BIN)/python -m pytest -n auto

# The documentation site (MkDocs, Material theme) -> site/; a warning fails the build. The
# test suite builds it too (tests/test_docs.py).
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

bench: $(STAMP)
	$(BIN)/python benchmarks/operator_throughput.py
	$(BIN)/python benchmarks/demo_matched_filter.py
	$(BIN)/python benchmarks/quality.py
	$(BIN)/python benchmarks/quality.py --scene tabletop
	$(BIN)/python benchmarks/quality.py --scene benchmarks/scenes/workshop.toml
	$(BIN)/python benchmarks/quality.py --radar dense-77g
	$(BIN)/python benchmarks/model_bias.py
	$(BIN)/python benchmarks/coherent_model.py
	$(BIN)/python benchmarks/object_contrast.py
