"""Where results came from: the package version, and the git commit of the checkout and whether it was dirty."""

from __future__ import annotations

import subprocess
from importlib import metadata
from pathlib import Path


def package_version() -> str:
    """The installed drivenav version."""
    try:
        return metadata.version("drivenav")
    except metadata.PackageNotFoundError:
        return "unknown"


def _git(*args: str) -> str | None:
    try:
        result = subprocess.run(
            ["git", *args], cwd=Path(__file__).parent, capture_output=True, text=True, check=False, timeout=10
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return result.stdout if result.returncode == 0 else None


def git_commit() -> str | None:
    """The short hash of the checkout drivenav runs from, if it is a git checkout."""
    commit = _git("rev-parse", "--short", "HEAD")
    return commit.strip() or None if commit is not None else None


def source_state() -> tuple[str | None, bool | None]:
    """The checkout's commit and whether its tree has uncommitted changes (None, None outside git)."""
    commit = git_commit()
    if commit is None:
        return None, None
    status = _git("status", "--porcelain", "--untracked-files=no")
    return commit, None if status is None else bool(status.strip())
