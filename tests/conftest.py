"""Shared fixtures: the packaged floor plans, a command-line runner, one torch thread for the tiny models."""

from __future__ import annotations

from drivenav.threads import limit_blas_threads

limit_blas_threads()  # before numpy loads

import importlib.metadata
import subprocess
import sys
import time
from collections.abc import Iterator
from functools import cache
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from drivenav import plugins
from drivenav.envs.embedded.rosmap import packaged_maps_dir
from drivenav.plugins import Registry

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


def until_records(process: subprocess.Popen[Any], results: Path, count: int, timeout: float = 240.0) -> None:
    """Wait until the run ``process`` runs has ``count`` records in ``results`` (or it ended, or ``timeout``)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and process.poll() is None:
        if results.exists() and len(results.read_text().splitlines()) >= count:
            return
        time.sleep(0.05)


def registries() -> dict[str, Registry[Any]]:
    """Every entry-point registry of drivenav, by group."""
    from drivenav.agent.explorers import EXPLORERS
    from drivenav.methods import METHOD_ROWS
    from drivenav.robot.registry import MOTIONS, SOURCES
    from drivenav.semantics.registry import GROUNDER_BACKENDS, REASONER_BACKENDS, SCORER_BACKENDS, SEGMENTER_BACKENDS
    from drivenav.worlds import WORLDS

    found: list[Registry[Any]] = [
        EXPLORERS, WORLDS, REASONER_BACKENDS, GROUNDER_BACKENDS, SEGMENTER_BACKENDS, SCORER_BACKENDS, SOURCES, MOTIONS,
        METHOD_ROWS,
    ]  # fmt: skip
    return {registry.group: registry for registry in found}


def plug_in(monkeypatch: pytest.MonkeyPatch, *points: tuple[str, str, str, str]) -> None:
    """Other packages' entry points for one test, each ``(group, name, module:attribute, distribution)``: every
    registry, and the settings' explorer sections, read them now (as a new process would) and forget them after the
    test."""
    from drivenav import settings

    declared = [SimpleNamespace(group=g, name=n, value=v, dist=SimpleNamespace(name=d)) for g, n, v, d in points]
    monkeypatch.setattr(plugins, "entry_points", lambda group: [p for p in declared if p.group == group])
    for registry in registries().values():
        monkeypatch.setattr(registry, "_loaded", {})
        monkeypatch.setitem(vars(registry), "declared", Registry.declared.func(registry))
    monkeypatch.setattr(settings, "explorer_settings_type", cache(settings.explorer_settings_type.__wrapped__))
