"""The farthest-frontier explorer's settings section (``explorer.farthest``) and its registration: a light module
(no behaviour imported), so that drivenav's settings read the section without loading the explorer. The entry also
declares what the explorer records, for the report and the pictures: its counters (the decisions table's columns,
the episode page's counters) and its own trace event (how the episode page and the pictures show it)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from drivenav.agent.config import CounterSpec, EventSpec, ExplorerEntry
from drivenav.ranges import LENGTH, Range, check_declared


@dataclass(frozen=True)
class FarthestConfig:
    """The farthest-frontier rule's one constant, and its range (checked wherever the section is made)."""

    max_travel_time: float = 12.0  # frontier points farther than this (weighted-FMM travel time, m) are not goals

    RANGES: ClassVar[Mapping[str, Range]] = {"max_travel_time": LENGTH}

    def __post_init__(self) -> None:
        check_declared(self)


COUNTERS = (
    CounterSpec("goals_chosen", "goals chosen"),
    CounterSpec("longest_goal", "longest goal (m)", kind="metres", format="{:.1f}"),
    CounterSpec("goals_skipped", "goals skipped", column=False),
)
"""The fields of :class:`~drivenav_example.explorer.FarthestCounters`: the goals chosen and the longest travel time
to one (columns of the decisions table, means per episode), the goals skipped as unreachable (the episode page
only)."""

GOAL_EVENT = EventSpec(
    "farthest_goal", ("frontier_id", "travel_time"), "square", (230, 120, 0), "farthest goal", at="target"
)
""":class:`~drivenav_example.explorer.FarthestGoal`, a new goal: the episode page lists its frontier and travel time;
the pictures draw an orange square at the goal's point."""

EXPLORER = ExplorerEntry(
    "farthest",
    FarthestConfig,
    "drivenav_example.explorer:FarthestExplorer",
    "the frontier point with the largest weighted-FMM travel time (up to max_travel_time), kept until explored",
    ("agent.enrich=false", "agent.verify=false"),
    counters=COUNTERS,
    events=(GOAL_EVENT,),
)
"""The entry point ``farthest = "drivenav_example.config:EXPLORER"`` (group ``drivenav.explorers``) names this."""
