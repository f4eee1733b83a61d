"""The farthest-frontier explorer's settings section (``explorer.farthest``) and its registration: a light module
(no behaviour imported), so that drivenav's settings read the section without loading the explorer."""

from __future__ import annotations

from dataclasses import dataclass

from drivenav.agent.config import ExplorerEntry


@dataclass(frozen=True)
class FarthestConfig:
    """The farthest-frontier rule's one constant."""

    max_travel_time: float = 12.0  # frontier points farther than this (weighted-FMM travel time) are not goals


EXPLORER = ExplorerEntry(
    "farthest",
    FarthestConfig,
    "drivenav_example.explorer:FarthestExplorer",
    "the frontier point with the largest weighted-FMM travel time (up to max_travel_time), kept until explored",
    ("agent.enrich=false", "agent.verify=false"),
)
"""The entry point ``farthest = "drivenav_example.config:EXPLORER"`` (group ``drivenav.explorers``) names this."""
