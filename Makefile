# Quick start: `make demo` and `make test`. Both create .venv and install the package when needed
# (with the test, gen, cluster and view extras, so the tiny generative-model, Ray batch and viewer tests run too).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
PYTEST_ARGS ?=

.PHONY: demo test test-slow setup clean

setup: $(STAMP)

$(STAMP): setup.cfg setup.py pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -e '.[test,gen,cluster,view]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/fluidnexus demo --overwrite

# the fast tier (CI) in two pytest workers, a test file each at a time (README, "Tests", has its measured time); the
# slow tier (tests marked slow: full diagnoses, memory peaks, long runs) with test-slow
test: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow" -n 2 --dist loadfile $(PYTEST_ARGS)

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow $(PYTEST_ARGS)

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
