"""Command-line values checked where a command reads them: paths, positive counts, episode counts, seeds.

A light module (no numpy): the command line and the worlds' options (:mod:`drivenav.worlds`) use it while the
parser is built. A bad value is one :class:`~drivenav.errors.InputError` (one line, exit status 2).
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from drivenav.errors import InputError

MAX_EPISODES = 1_000_000  # more episodes than any benchmark split: a typo, not a run


def path(text: str) -> Path:
    """A path option's value; an empty one (which would mean the current folder) is refused."""
    if not text:
        raise argparse.ArgumentTypeError("expected a path, got an empty string")
    return Path(text)


def is_count(text: object) -> bool:
    """Whether an option's text is a whole number in decimal digits (``str.isdigit`` also holds for '²', which
    ``int`` refuses)."""
    return re.fullmatch("[0-9]+", str(text)) is not None


def positive(value: int, option: str) -> int:
    """``value`` when it is at least 1."""
    if value < 1:
        raise InputError("command line", option, "a positive integer", value)
    return value


def episode_count(value: int, option: str) -> int:
    """A number of episodes: positive and at most :data:`MAX_EPISODES`."""
    count = positive(value, option)
    if count > MAX_EPISODES:
        raise InputError("command line", option, f"a number of episodes up to {MAX_EPISODES:,}", count)
    return count


def seed(value: int) -> int:
    """A ``--seed``: an integer >= 0."""
    if value < 0:
        raise InputError("command line", "--seed", "an integer >= 0", value)
    return value
