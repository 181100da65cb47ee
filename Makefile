# hubo-cli: every target installs into .venv first when needed.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: run test bench lint clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,viz]'
	@touch $(STAMP)

run: $(STAMP)
	$(BIN)/hubo task cut-rectangle --video

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python -m hubo_cli.bench $(BENCH)

lint: $(STAMP)
	$(BIN)/ruff check hubo_cli tests tools

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache runs
