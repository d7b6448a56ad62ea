# Two commands on a fresh machine (Python 3.11, 3.12 or 3.13, pip, make):
#   make reproduce   # .venv + pinned deps + snakemake --cores 2 at the default scale
#   make test        # .venv + pinned deps + the test suite
# Both reuse the environment (and numba's on-disk cache) on a second call.

# The first of python3.11, python3.12, python3.13, python3 found; `make test PYTHON=python3.13`
# picks one (a .venv of another version is rebuilt).
PYTHON ?= $(shell command -v python3.11 || command -v python3.12 || command -v python3.13 || command -v python3)
PYVER := $(shell $(PYTHON) -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.granpipe-installed-$(PYVER)
CORES ?= 2
# Test selection: everything (physics validations and the real-SLURM test included), on
# $(CORES) pytest workers (pytest-xdist; each worker builds the session fixtures it needs).
PYTEST_ARGS ?=
# One BLAS thread per process: Snakemake and pytest already run processes side by side,
# and oversubscribed BLAS threads slowed small fits tenfold on 2 cores.
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1
# Rules call the `granpipe` console script: the environment's bin comes first on PATH.
export PATH := $(CURDIR)/$(BIN):$(PATH)

.PHONY: env reproduce test lint bench bench-reference quick report clean-results

$(STAMP): pyproject.toml constraints.txt
	@$(PYTHON) -c 'import sys; v = sys.version_info[:2]; assert (3, 11) <= v <= (3, 13), "granpipe needs Python 3.11-3.13, found " + sys.version'
	@if [ -x $(BIN)/python ] && [ "$$($(BIN)/python -c 'import sys; print("%d.%d" % sys.version_info[:2])')" != "$(PYVER)" ]; then \
		echo "$(VENV) holds another Python: rebuilding it with $(PYVER)"; rm -rf $(VENV); fi
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade "pip>=24"
	$(BIN)/python -m pip install --quiet -c constraints.txt -e ".[test]"
	touch $(STAMP)

env: $(STAMP)

reproduce: env
	$(BIN)/snakemake --cores $(CORES)

quick: env
	$(BIN)/snakemake --cores $(CORES) --configfile config/quick.yaml

test: env
	$(BIN)/python -m pytest -n $(CORES) --durations=15 $(PYTEST_ARGS)

lint: env
	$(BIN)/ruff check . && $(BIN)/ruff format --check . && $(BIN)/snakemake --lint

bench: env
	$(BIN)/python benchmarks/engine.py
	$(BIN)/python benchmarks/engine_passes.py

# the reference (LAMMPS GRANULAR, Debian's build) timed beside the engine
bench-reference: env
	tools/lammps/install.sh
	$(BIN)/python benchmarks/lammps_reference.py

report: env
	$(BIN)/snakemake --cores $(CORES) --report results/report.zip

clean-results:
	rm -rf results/default results/quick .snakemake
