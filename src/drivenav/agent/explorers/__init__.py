"""The exploration methods by name (``explorer.name``): drivenav's own and other packages' (entry-point group
``drivenav.explorers``, :mod:`drivenav.plugins`).

Each is an :class:`~drivenav.agent.config.ExplorerEntry` in a module that loads no agent behaviour (its config
class and its entry), so the settings read the chosen explorer's section without importing its behaviour.
drivenav's own:

- ``directions``: DRIVE-Nav's persistent directions, inspection events and reasoner decisions (paper Sec. IV-A);
  with ``decision_scan`` the ``direction-360`` and ``frontier`` baselines;
- ``greedy``: the nearest frontier (Table II's greedy baseline);
- ``vlfm``: VLFM's value map and highest-value frontier (Yokoyama et al., ICRA 2024);
- ``apexnav``: ApexNav's semantic (TSP) or geometric mode by the value map's spread, and dormant frontiers (Zhang et
  al., RA-L 2025).

An explorer's settings section is ``explorer.<key>``, its key made from its name by :func:`settings_key` (any
entry-point name maps to an identifier: ``my-explorer`` -> ``explorer.my_explorer``); only the chosen explorer's
section is in a run's settings (:mod:`drivenav.settings`).
"""

from __future__ import annotations

import keyword

from drivenav.agent.config import ExplorerEntry
from drivenav.plugins import Registry

DEFAULT_EXPLORER = "directions"

BUILT_IN_EXPLORERS = {
    "directions": "drivenav.agent.explorers.drive_nav.config:EXPLORER",
    "greedy": "drivenav.agent.explorers.greedy.config:EXPLORER",
    "vlfm": "drivenav.agent.explorers.vlfm.config:EXPLORER",
    "apexnav": "drivenav.agent.explorers.apexnav.config:EXPLORER",
}
"""drivenav's own explorers: name -> the ``module:attribute`` of their entry (also declared in pyproject.toml)."""

EXPLORERS: Registry[ExplorerEntry] = Registry(
    "drivenav.explorers",
    BUILT_IN_EXPLORERS,
    lambda part: isinstance(part, ExplorerEntry),
    "explorer entry (drivenav.agent.config.ExplorerEntry)",
    "explorer.name",
    named=lambda entry: entry.name,
)
"""Every explorer by name: the built-ins, then plug-ins."""


def explorer_entry(name: str) -> ExplorerEntry:
    """The registered explorer ``name``; an unknown or broken one is one :class:`~drivenav.errors.InputError` line.
    An entry registered under another name than its own is broken too (its settings section would not be found)."""
    return EXPLORERS.get(name)


def settings_key(name: str) -> str:
    """The settings key of the explorer ``name`` (its section ``explorer.<key>``), by a rule that takes any
    entry-point name: every character but an ASCII letter, digit or ``_`` becomes ``_`` (``my-explorer`` ->
    ``my_explorer``, ``a.b`` -> ``a_b``); a key that does not start with a letter gets an ``x`` in front (``3d``
    -> ``x3d``, ``_x`` -> ``x_x``, the empty name -> ``x``); a Python keyword, and ``name`` (the key that picks
    the explorer), get a ``_`` after (``class`` -> ``class_``, ``name`` -> ``name_``). Any other ASCII identifier
    that starts with a letter is its own key: the built-ins' keys are their names. Two names may map to one key:
    the earlier explorer keeps it (:func:`explorer_key`)."""
    key = "".join(ch if ch.isascii() and (ch.isalnum() or ch == "_") else "_" for ch in name)
    if not (key[:1].isascii() and key[:1].isalpha()):
        key = f"x{key}"
    return f"{key}_" if keyword.iskeyword(key) or key == "name" else key


def section_keys() -> dict[str, str]:
    """Every declared explorer's settings key -> its name, nothing imported; where two names map to one key, the
    earlier explorer's (built-ins first, then plug-ins by name)."""
    keys: dict[str, str] = {}
    for name in EXPLORERS.names:
        keys.setdefault(settings_key(name), name)
    return keys


def explorer_key(name: str) -> str:
    """The settings key of the declared explorer ``name``; one :class:`~drivenav.errors.InputError` line (the
    plug-in's, :meth:`~drivenav.plugins.Registry.broken`) when an earlier explorer holds the same key."""
    key = settings_key(name)
    holder = section_keys().get(key, name)
    if holder != name and name in EXPLORERS.names:
        raise EXPLORERS.broken(name, f"the settings key explorer.{key}, which explorer {holder!r} holds")
    return key
