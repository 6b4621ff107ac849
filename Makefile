# Quick start: `make demo` and `make test`. Both create .venv and install the package when needed
# (with the test, gen and cluster extras, so the tiny generative-model and Ray batch tests run too).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
PYTEST_ARGS ?=

.PHONY: demo test setup clean

setup: $(STAMP)

$(STAMP): setup.cfg pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -e '.[test,gen,cluster]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/fluidnexus demo --overwrite

test: $(STAMP)
	$(BIN)/python -m pytest -q $(PYTEST_ARGS)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
