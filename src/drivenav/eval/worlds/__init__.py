"""The worlds a run can use, by ``--env`` name: one :class:`~drivenav.eval.worlds.entry.WorldEntry` each.

The command line (its options, the run's spec, episodes and title) and ``drivenav viz`` (a run's world rebuilt
from ``run.json``) loop over :data:`WORLDS`; neither names a world. A new world is one module (its
:class:`~drivenav.envs.base.EnvSpec` and env, and a ``WorldEntry``) and one :func:`register` call; see
``tests/test_world_registry.py`` for a world of a few lines.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from drivenav.errors import InputError
from drivenav.eval.worlds.embedded import EMBEDDED
from drivenav.eval.worlds.entry import WorldEntry
from drivenav.eval.worlds.habitat import HABITAT
from drivenav.eval.worlds.robot import ROBOT
from drivenav.jsonstream import JsonObject

if TYPE_CHECKING:
    from drivenav.envs.base import EnvSpec

DEFAULT_WORLD = EMBEDDED.name

WORLDS: dict[str, WorldEntry] = {}
"""Every world by ``--env`` name, in the order ``--help`` lists them."""


def register(entry: WorldEntry) -> WorldEntry:
    """Add ``entry`` to :data:`WORLDS` (a name is taken once)."""
    if entry.name in WORLDS:
        raise ValueError(f"world {entry.name} is registered twice")
    WORLDS[entry.name] = entry
    return entry


for _built_in in (EMBEDDED, HABITAT, ROBOT):
    register(_built_in)


def chosen_world(args: argparse.Namespace) -> WorldEntry:
    """The world of a command's ``--env`` (commands without one run on the default world)."""
    return WORLDS[getattr(args, "env", DEFAULT_WORLD)]


def world_named(name: str) -> WorldEntry:
    """The registered world ``name`` (a command bound to one world, e.g. ``drivenav run`` and the robot)."""
    return WORLDS[name]


def recorded_world(record: JsonObject, source: str | Path) -> tuple[WorldEntry, EnvSpec]:
    """A run's world and its spec from the world record of its ``run.json`` (``config.env``)."""
    name = record.get("name")
    entry = WORLDS.get(str(name)) if isinstance(name, str) else None
    if entry is None:
        raise InputError(source, "config.env.name", f"a run in {' or '.join(WORLDS)}", name)
    return entry, entry.rebuild(record, source)


__all__ = ["DEFAULT_WORLD", "WORLDS", "WorldEntry", "chosen_world", "recorded_world", "register", "world_named"]
