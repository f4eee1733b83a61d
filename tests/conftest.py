"""Shared fixtures: the packaged floor plans, a command-line runner, one torch thread for the tiny models."""

from __future__ import annotations

from drivenav.threads import limit_blas_threads

limit_blas_threads()  # before numpy loads

import importlib.metadata
import subprocess
import sys
from collections.abc import Iterator
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


@pytest.fixture(scope="module")
def one_torch_thread() -> Iterator[None]:
    """Tiny models gain nothing from threads; on shared cores extra threads only oversubscribe them (a module of
    torch tests uses it with ``pytestmark = pytest.mark.usefixtures("one_torch_thread")``)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


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
