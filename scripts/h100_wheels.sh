#!/usr/bin/env bash
# The packages scripts/h100_grounding.sh installs on the GPU machine, which has no network, downloaded here into
# .whl/ (ignored by git: hand it over with the device's `carry: [".whl"]`): the wheels of mobilesam-mirror, omegaconf
# and pyzmq for Python 3.12 on x86-64 Linux, and scikit-fmm's source (it publishes no wheel; the GPU script builds its
# two extension modules with the machine's C++ compiler).
#
#   bash scripts/h100_wheels.sh [PYTHON]     (PYTHON: the pip to download with; default .venv/bin/python)
set -euo pipefail

PYTHON=${1:-$([ -x .venv/bin/python ] && echo .venv/bin/python || echo python3)}
mkdir -p .whl
"$PYTHON" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --platform manylinux2014_x86_64 \
    --platform manylinux_2_28_x86_64 --platform any -d .whl mobilesam-mirror==1.0.0 omegaconf==2.4.0 pyzmq==27.3.0
# --no-binary for scikit-fmm alone: its build backend (meson, ninja) still comes as wheels
"$PYTHON" -m pip download -q --no-deps --no-binary scikit-fmm -d .whl scikit-fmm==2025.6.23
ls -l .whl
