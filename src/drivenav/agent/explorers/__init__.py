"""The exploration methods by name (``explorer.name``): drivenav's own and other packages' (entry-point group
``drivenav.explorers``, :mod:`drivenav.plugins`).

Each is an :class:`~drivenav.agent.config.ExplorerEntry` in a module that loads no agent behaviour (its config
class and its entry), so the settings read every explorer's section without importing one. drivenav's own:

- ``directions``: DRIVE-Nav's persistent directions, inspection events and reasoner decisions (paper Sec. IV-A);
  with ``decision_scan`` the ``direction-360`` and ``frontier`` baselines;
- ``greedy``: the nearest frontier (Table II's greedy baseline);
- ``vlfm``: VLFM's value map and highest-value frontier (Yokoyama et al., ICRA 2024);
- ``apexnav``: ApexNav's semantic (TSP) or geometric mode by the value map's spread, and dormant frontiers (Zhang et
  al., RA-L 2025).
"""

from __future__ import annotations

from drivenav.agent.config import ExplorerEntry
from drivenav.plugins import Registry

DEFAULT_EXPLORER = "directions"

BUILT_IN_EXPLORERS = {
    "directions": "drivenav.agent.explorers.directions.config:EXPLORER",
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
