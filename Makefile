# Quick start: `make demo` and `make test`. Both create .venv and install the package when needed: the demo the
# package alone (55 s on the 2-core VM against 134 s with every extra), the tests with the test, gen, cluster and view
# extras too, so the tiny generative-model, Ray batch and viewer tests run.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
BASE_STAMP := $(VENV)/.installed-base
STAMP := $(VENV)/.installed
PYTEST_ARGS ?=

.PHONY: demo test test-slow setup clean

setup: $(STAMP)

$(BASE_STAMP): setup.cfg setup.py pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -e .
	touch $(BASE_STAMP)

$(STAMP): $(BASE_STAMP)
	$(BIN)/python -m pip install --quiet -e '.[test,gen,cluster,view]'
	touch $(STAMP)

demo: $(BASE_STAMP)
	$(BIN)/fluidnexus demo --overwrite

# the fast tier (CI) in two pytest workers, a test file each at a time (README, "Tests", has its measured time); the
# slow tier (tests marked slow: full diagnoses, memory peaks, long runs) with test-slow
test: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow" -n 2 --dist loadfile $(PYTEST_ARGS)

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow $(PYTEST_ARGS)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
