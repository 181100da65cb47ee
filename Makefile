# hubo-cli: every target installs into .venv first when needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
CORE   := $(VENV)/.core-stamp
LIBACH := $(VENV)/lib/libach.so

.PHONY: run test test-portable warm bench lint docs clean

LOCK   := requirements.lock
# the extras make installs: the suite's, the pictures', the docs site's (the suite builds it)
# and Dask's dashboard
EXTRAS := test,viz,docs,bokeh

.PHONY: update-lock

# Python keeps the bytecode it compiles (__pycache__, ignored by git) for every command here,
# whatever the environment says: with PYTHONDONTWRITEBYTECODE=1 (this machine's shells set
# it) every process of the suite compiled this project's modules from source again, 0.3 s of
# CPU each, and each pytest worker rewrote every test module's asserts, 10.3 s of CPU for the
# collection against 4.2 s with the rewritten modules kept.
unexport PYTHONDONTWRITEBYTECODE

# Installs exactly the versions in $(LOCK) (the ones the test suite passed with). Without
# compiling every installed module to bytecode (--no-compile): pip compiled all 9,000 of
# them in one process (about 20 s of CPU of its 48); Python compiles those a command imports
# on their first import and keeps them (above).
# In two steps: the project with its own dependencies ($(CORE), all that `make warm` needs),
# then the extras by the project's name (the installed project is not built again), which
# .ci/run installs while `make warm` compiles. Of the extras' packages the warm-up's runs
# import pyarrow (a log's Parquet file takes its schema from it when it is there) and,
# through it, typing-extensions: those two come first, so that no run imports them half
# installed.
$(CORE): pyproject.toml $(LOCK)
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --no-compile -c $(LOCK) --upgrade pip
	$(BIN)/python -m pip install --quiet --no-compile -c $(LOCK) -e . pyarrow typing-extensions
	@touch $(CORE)

$(STAMP): $(CORE) | $(LIBACH)
	$(BIN)/python -m pip install --quiet --no-compile -c $(LOCK) 'hubo-cli[$(EXTRAS)]'
	@touch $(STAMP)

# libach, the shared-memory IPC library of hubo-ach's channels, is on no package registry: its
# source (third_party/ach, golems/ach's BSD library files) is built into the environment, where
# the hardware driver finds it after HUBO_LIBACH and the loader path (a lab's own libach), so
# the suite's tests of the real-robot path run everywhere (0.6 s of CPU). Needs a C compiler.
ACH_DIR := third_party/ach
$(LIBACH): $(wildcard $(ACH_DIR)/src/*.c $(ACH_DIR)/include/*.h $(ACH_DIR)/include/*/*.h) | $(CORE)
	$(CC) -O2 -shared -fPIC -I$(ACH_DIR)/include $(ACH_DIR)/src/libach*.c -o $@ -lpthread -lrt

# Resolves the newest versions pyproject.toml allows in a scratch virtualenv and writes them
# to $(LOCK); run `make test` afterwards and commit the lock file if it passes.
update-lock:
	rm -rf .lock-venv
	$(PYTHON) -m venv .lock-venv
	.lock-venv/bin/python -m pip install --quiet --upgrade pip
	.lock-venv/bin/python -m pip install --quiet -e '.[$(EXTRAS)]'
	{ echo "# hubo-cli: the versions the test suite passed with (make update-lock writes it)."; \
	  .lock-venv/bin/python -m pip freeze --all --exclude-editable; } > $(LOCK)
	rm -rf .lock-venv

run: $(STAMP)
	$(BIN)/hubo task cut-rectangle --video

# The tests marked `realtime` (a daemon playing the robot in real time over libach channels)
# run after the others, one at a time; their modules take the marks from
# tests/realtime_support.py, which says why.
REALTIME_TESTS = $(shell grep -l "realtime_support" tests/test_*.py)

test: $(STAMP) $(LIBACH)
	$(BIN)/python -m pytest -q -m "not realtime"
	$(BIN)/python -m pytest -q -n 0 -m realtime $(REALTIME_TESTS)

# The tests that assert a physical outcome (marked `physical`) again on the code paths of a
# CPU without AVX-512: numpy's dispatch (X86_V4 is numpy 2.4's name for the AVX-512 group, the
# AVX512* names the earlier ones'), OpenBLAS's Haswell kernels, and numba compiling for a
# Haswell (NUMBA_CPU_NAME alone keeps the host's AVX-512 features: the empty feature list
# drops them). numba keys its cache by CPU name and features; its Haswell code, and the
# workspace masks computed with it, are cached apart all the same, so neither run loads what
# the other computed. The last bits differ, so a figure asserted at a knife edge fails here as
# it would on such a machine.
PORTABLE_ENV := NPY_DISABLE_CPU_FEATURES="AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL X86_V4 AVX512_ICL AVX512_SPR" \
	OPENBLAS_CORETYPE=Haswell NUMBA_CPU_NAME=haswell NUMBA_CPU_FEATURES= \
	NUMBA_CACHE_DIR="$(CURDIR)/$(VENV)/portable-cache/numba" HUBO_CACHE_DIR="$(CURDIR)/$(VENV)/portable-cache"

# Only the test files that name the mark are collected (a third of them): each worker then
# imports and collects in about 5 s of CPU instead of 10 s, with the same tests selected. A
# module that marks its tests `physical` names the mark in its own text (the conftest marks
# none), so `grep -il physical` finds it.
PHYSICAL_TESTS = $(shell grep -il physical tests/test_*.py)

test-portable: $(STAMP) $(LIBACH)
	$(PORTABLE_ENV) $(BIN)/python -m pytest -q -m "physical and not realtime" $(PHYSICAL_TESTS)
	$(PORTABLE_ENV) $(BIN)/python -m pytest -q -n 0 -m "physical and realtime" \
		$(filter $(REALTIME_TESTS),$(PHYSICAL_TESTS))

# Compiles the kernels of both code paths into their caches at once, one process each
# (tests/warm_kernels.py; the two caches stay apart): .ci/run's step before the two test runs,
# which then only load them. Each path alone compiles in about 60 s of CPU on a cold cache.
warm: $(CORE)
	$(BIN)/python tests/warm_kernels.py arms legs & pid=$$!; \
	$(PORTABLE_ENV) $(BIN)/python tests/warm_kernels.py arms legs; portable=$$?; \
	wait $$pid && exit $$portable

bench: $(STAMP)
	$(BIN)/python -m hubo_cli.bench $(BENCH)

# the documentation site, warnings as errors, into site/
docs: $(STAMP)
	$(BIN)/mkdocs build --strict --site-dir site

lint: $(STAMP)
	$(BIN)/ruff check hubo_cli tests tools

clean:
	rm -rf $(VENV) .lock-venv build dist *.egg-info .pytest_cache runs site
