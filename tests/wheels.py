"""Fresh venvs for the tests that install drivenav as a user would: its wheel built from this tree and installed
offline, with its dependencies and its build backend from the wheelhouse that ``make test`` fills
(``build/wheelhouse``, or ``DRIVENAV_WHEELHOUSE``), and commands run there with nothing leading back to this tree."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

WHEELHOUSE = Path(os.environ.get("DRIVENAV_WHEELHOUSE", REPO / "build" / "wheelhouse"))
OFFLINE = ("--no-index", "--find-links", str(WHEELHOUSE))


def run(*args: str | Path, cwd: Path, env: dict[str, str] | None = None) -> str:
    """``args`` run to success (else the test fails with the command's exit status and its output's tail)."""
    done = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{args}: exit {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def copy_tree(target: Path) -> Path:
    """What a source distribution holds: pyproject, README and the package sources (no builds, no caches)."""
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, target / name)
    ignore = shutil.ignore_patterns("__pycache__", "_compiled_kernels*", "*.egg-info")
    shutil.copytree(REPO / "src", target / "src", ignore=ignore)
    return target


def build_wheel(source: Path, dist: Path) -> Path:
    """The wheel of the project in ``source`` (its build backend from the wheelhouse), written to ``dist``."""
    run(sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", *OFFLINE, "-w", dist, source, cwd=source)
    return max(dist.glob("*.whl"), key=lambda wheel: wheel.stat().st_mtime)


def fresh_venv(root: Path, *projects: Path) -> Path:
    """A new venv under ``root`` with drivenav's wheel, the wheels of ``projects`` (folders with a pyproject.toml)
    and their declared dependencies, nothing else; its python."""
    if not (WHEELHOUSE / ".downloaded").is_file():
        pytest.skip(f"no wheelhouse at {WHEELHOUSE}: `make test` fills it (make build/wheelhouse/.downloaded)")
    (root / "source").mkdir()
    wheels = [build_wheel(project, root / "dist") for project in (copy_tree(root / "source"), *projects)]
    run(sys.executable, "-m", "venv", root / "venv", cwd=root)
    python = root / "venv" / "bin" / "python"
    run(python, "-m", "pip", "install", "-q", *OFFLINE, *wheels, cwd=root)
    return python


def clean_env() -> dict[str, str]:
    """This environment without what could lead the installed drivenav back to this tree or change its kernels."""
    return {k: v for k, v in os.environ.items() if k not in ("DRIVENAV_SHARED", "PYTHONPATH", "DRIVENAV_KERNELS")}
