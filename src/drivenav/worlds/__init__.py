"""The worlds a run can use, by ``--env`` name: one :class:`~drivenav.worlds.entry.WorldEntry` each,
drivenav's own and other packages' (entry-point group ``drivenav.worlds``, :mod:`drivenav.plugins`).

The command line (its options, the run's spec, episodes and title) and ``drivenav viz`` (a run's world rebuilt
from ``run.json``) go through :data:`WORLDS`; neither names a world. A new world is one module (its
:class:`~drivenav.envs.base.EnvSpec` and env, and a ``WorldEntry``) and one entry point; see
``tests/test_world_registry.py`` for a world of a few lines and docs/extending.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.plugins import Registry
from drivenav.worlds.entry import WorldEntry

if TYPE_CHECKING:
    from drivenav.envs.base import EnvSpec

DEFAULT_WORLD = "embedded"

BUILT_IN_WORLDS = {
    "embedded": "drivenav.worlds.embedded:EMBEDDED",
    "habitat": "drivenav.worlds.habitat:HABITAT",
    "robot": "drivenav.worlds.robot:ROBOT",
}
"""drivenav's own worlds: ``--env`` name -> the ``module:attribute`` of their entry (also declared in
pyproject.toml), in the order ``--help`` lists them."""

WORLDS: Registry[WorldEntry] = Registry(
    "drivenav.worlds",
    BUILT_IN_WORLDS,
    lambda part: isinstance(part, WorldEntry),
    "world entry (drivenav.worlds.entry.WorldEntry)",
    "--env",
    named=lambda entry: entry.name,
)
"""Every world by ``--env`` name: the built-ins, then plug-ins."""


def usable_worlds() -> list[WorldEntry]:
    """Every world that loads (a broken plug-in is refused when it is chosen): the command line's world options."""
    return list(WORLDS.usable().values())


def offered_worlds(args: argparse.Namespace) -> list[WorldEntry]:
    """Every world that loads and whose options the command line parsed into ``args`` took (a plug-in world whose
    options clash is left out: its options are none of the command's)."""
    return list(WORLDS.offered(args).values())


def chosen_world(args: argparse.Namespace) -> WorldEntry:
    """The world of a command's ``--env`` (commands without one run on the default world); a broken plug-in, or one
    whose options the command refused, is one :class:`~drivenav.errors.InputError` line."""
    return WORLDS.chosen(args, getattr(args, "env", DEFAULT_WORLD))


def world_named(name: str) -> WorldEntry:
    """The registered world ``name`` (a command bound to one world, e.g. ``drivenav run`` and the robot)."""
    return WORLDS.get(name)


def recorded_world(record: JsonObject, source: str | Path) -> tuple[WorldEntry, EnvSpec]:
    """A run's world and its spec from the world record of its ``run.json`` (``config.env``)."""
    name = record.get("name")
    if not isinstance(name, str) or name not in WORLDS.names:
        raise InputError(source, "config.env.name", f"a run in {' or '.join(WORLDS.names)}", name)
    entry = WORLDS.get(name)
    with WORLDS.guard(name, "rebuild"):
        spec = entry.rebuild(record, source)
    return entry, spec


__all__ = [
    "BUILT_IN_WORLDS",
    "DEFAULT_WORLD",
    "WORLDS",
    "WorldEntry",
    "chosen_world",
    "offered_worlds",
    "recorded_world",
    "usable_worlds",
    "world_named",
]
