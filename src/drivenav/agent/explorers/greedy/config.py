"""The greedy nearest-frontier explorer (paper Table II's greedy baseline): its settings section
``explorer.greedy`` and its registration."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from drivenav.agent.config import CounterSpec, ExplorerEntry
from drivenav.agent.explorers.drive_nav.config import ACTIVITIES, DECISIONS
from drivenav.ranges import LENGTH, Range, check_declared


@dataclass(frozen=True)
class GreedyConfig:
    """The greedy baseline's tuning (ours: the paper does not give it)."""

    min_goal_distance: float = 1.0  # metres: frontier points nearer than this are not goals (all are if none is)

    RANGES: ClassVar[Mapping[str, Range]] = {"min_goal_distance": LENGTH}

    def __post_init__(self) -> None:
        check_declared(self)


EXPLORER = ExplorerEntry(
    "greedy",
    GreedyConfig,
    "drivenav.agent.explorers.greedy.explorer:GreedyExplorer",
    "the nearest frontier point by weighted-FMM travel time, kept until explored (no views, no reasoner)",
    ("agent.enrich=false", "agent.verify=false"),
    counters=(DECISIONS, CounterSpec("goals_skipped", "goals skipped", column=False)),
    activities=ACTIVITIES,
)
