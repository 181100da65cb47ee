# hubo-cli: every target installs into .venv first when needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: run test bench lint docs clean

LOCK   := requirements.lock
# the extras make installs: the suite's, the pictures', the docs site's (the suite builds it)
# and Dask's dashboard
EXTRAS := test,viz,docs,bokeh

.PHONY: update-lock

# Installs exactly the versions in $(LOCK) (the ones the test suite passed with).
$(STAMP): pyproject.toml $(LOCK)
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -c $(LOCK) --upgrade pip
	$(BIN)/python -m pip install --quiet -c $(LOCK) -e '.[$(EXTRAS)]'
	@touch $(STAMP)

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

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python -m hubo_cli.bench $(BENCH)

# the documentation site, warnings as errors, into site/
docs: $(STAMP)
	$(BIN)/mkdocs build --strict --site-dir site

lint: $(STAMP)
	$(BIN)/ruff check hubo_cli tests tools

clean:
	rm -rf $(VENV) .lock-venv build dist *.egg-info .pytest_cache runs site
