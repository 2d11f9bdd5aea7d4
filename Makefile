# Two entry points: `make demo` and `make test`. Both build .venv when missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-all bench peers venv clean

venv: $(STAMP)

$(STAMP): pyproject.toml studies/pyproject.toml Makefile src/sensorless/regressor/native_kernel.cpp src/sensorless/regressor/observer_kernel.cpp src/sensorless/regressor/native_contact.cpp src/sensorless/regressor/native_friction.cpp
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# The local CPU build of torch must come first; an unpinned torch pulls CUDA wheels.
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[all]'
	# The studies (simulations, experiments, benchmarks, example data, demo): a sibling package whose
	# commands join `sensorless` through entry points.
	$(PY) -m pip install --quiet -e studies
	# Optional C++ regressor kernel (sensorless.regressor.native); without a compiler the Python path is used.
	$(PY) -m sensorless.regressor.native_build || true
	# Bytecode for the editable sources, as pip writes it for installed packages: ~0.2 s less at every
	# command's start where PYTHONDONTWRITEBYTECODE keeps Python from caching it (docs/speed.md).
	$(PY) -m compileall -q src studies/src
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/sensorless demo --out demo_output --force

# One BLAS thread per pytest worker: two workers on two cores; threaded BLAS under
# contention made small solves 50x slower.
test: $(STAMP)
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 $(PY) -m pytest -q -n 2 tests studies/tests || [ $$? -eq 5 ]

test-all: $(STAMP)
	$(PY) -m pytest -q -m '' tests studies/tests

bench: $(STAMP)
	$(VENV)/bin/sensorless benchmark identify   # sensorless-bench/identify.json (the record: --out studies/benchmarks/results/identify.json)

# The peers of `sensorless benchmark peers --against figaroh,rigeo`, each in its own venv outside the
# repository (rigeo ships no regressor: its driver uses Pinocchio). PEERS_DIR must match --peer-venv.
PEERS_DIR ?= $(or $(XDG_CACHE_HOME),$(HOME)/.cache)/sensorless-peers
peers:
	test -x $(PEERS_DIR)/figaroh/bin/python || $(PYTHON) -m venv $(PEERS_DIR)/figaroh
	$(PEERS_DIR)/figaroh/bin/python -m pip install --quiet figaroh==1.0.2
	test -x $(PEERS_DIR)/rigeo/bin/python || $(PYTHON) -m venv $(PEERS_DIR)/rigeo
	$(PEERS_DIR)/rigeo/bin/python -m pip install --quiet rigeo==0.2.0 pin==4.1.0

clean:
	rm -rf $(VENV) demo_output
