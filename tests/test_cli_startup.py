"""Commands that do no work start fast: building the command line (``drivenav --help``) loads no numerical module
(numpy alone takes a few hundred milliseconds to import). Checked by what is imported, not by a clock."""

from __future__ import annotations

import subprocess
import sys

from conftest import REPO

HEAVY = ("numpy", "scipy", "numba", "omegaconf", "zmq", "torch", "drivenav.agent", "drivenav.settings")


def test_the_command_line_is_built_without_numerical_modules() -> None:
    probe = (
        "import sys; from drivenav.cli import build_parser; build_parser(); "
        f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=REPO, check=True)
    assert result.stdout.strip() == ""


def test_help_prints_every_command() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "drivenav.cli", "--help"], capture_output=True, text=True, cwd=REPO, check=True
    )
    for command in ("eval", "run", "robot", "bench", "viz", "doctor"):
        assert command in result.stdout
