"""Shared fixtures: the packaged floor plans and a command-line runner."""

from __future__ import annotations

from drivenav.threads import limit_blas_threads

limit_blas_threads()  # before numpy loads

import importlib.metadata
import subprocess
import sys
from pathlib import Path

import pytest

from drivenav.envs.embedded.rosmap import packaged_maps_dir

REPO = Path(__file__).resolve().parents[1]


def _has_habitat_lab() -> bool:
    try:
        importlib.metadata.version("habitat-lab")  # not find_spec: tests/habitat itself is a namespace package
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


# tests/habitat/ runs in .venv-habitat (habitat-lab pins numpy 1.26): `make test-habitat`, part of `make test`.
collect_ignore = [] if _has_habitat_lab() else ["habitat"]


@pytest.fixture
def maps_dir() -> Path:
    """The nine real floor plans shipped with drivenav (the ``--scenes`` part ``maps``)."""
    return packaged_maps_dir()


def run_cli(*args: str, timeout: float = 600.0) -> subprocess.CompletedProcess[str]:
    """Run ``drivenav ARGS`` in a fresh interpreter, capturing output."""
    return subprocess.run(
        [sys.executable, "-m", "drivenav.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=REPO,
        check=False,
    )
