"""DRIVE-Nav's explorer (paper Sec. IV-A): its settings section ``explorer.directions`` and its registration."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from drivenav.agent.config import CounterSpec, ExplorerEntry
from drivenav.ranges import STEPS, UNIT, Range, check_declared


@dataclass(frozen=True)
class DirectionsConfig:
    """The directions explorer's switches and tuning; the paper's constants it reads are ``paper.directions`` and
    ``paper.inspection`` (:class:`~drivenav.paper.DriveNavConfig`).

    The switches after ``reidentify_steps`` go beyond the paper (the ``drive-nav-plus`` method, docs/agent.md
    "Beyond the paper"); each is off by default, so ``drive-nav`` and every other method is the paper's agent.
    """

    decision_scan: bool = False  # True: a full 360 deg scan at every decision point (Table II: direction-360)
    reidentify_steps: int = 500  # ours: steps a removed direction is remembered, to recognise it under a fresh label
    skip_void_events: bool = False  # no reasoner question with nothing new to judge: a void event, a forced choice
    return_aware: bool = False  # a turn back finishes the near remainder of the chosen direction first
    settle_steps: int = 0  # steps a direction is tracked before it may start an inspection event (0: the paper's)
    target_check: float = 0.0  # image-text score of a new view at which it is judged at once (0: no check)

    RANGES: ClassVar[Mapping[str, Range]] = {"reidentify_steps": STEPS, "settle_steps": STEPS, "target_check": UNIT}

    def __post_init__(self) -> None:
        check_declared(self)


TRIGGERS = ("scan", "inspection", "vanished", "stuck")
"""What triggered a decision (the ``decisions`` counter's kinds): the start scan (and every decision of the 360 deg
scanning methods), an inspection event, the followed direction gone, the planner stuck."""

DECISIONS = CounterSpec("decisions", kind="by_kind", kinds=TRIGGERS)
"""Reasoner decisions by trigger (its greedy baseline counts its frontier choices alike)."""
COUNTERS = (
    DECISIONS,
    CounterSpec("dead_end_decisions", "dead end"),
    CounterSpec("inspection_events", "inspection events"),
    CounterSpec("labels_created", "labels created"),
    CounterSpec("labels_merged", "merged"),
    CounterSpec("labels_removed", "removed"),
    CounterSpec("labels_reidentified", "re-identified"),
    CounterSpec("followed_through_relabel", "followed through relabel"),
    CounterSpec("selected_lost", "followed lost"),
    CounterSpec("void_events", "void events", column=False),
    CounterSpec("forced_choices", "forced choices", column=False),
)
"""DRIVE-Nav's counters (:class:`~drivenav.agent.explorers.drive_nav.memory.DirectionCounters`), in the decisions
table's order."""
ACTIVITIES = ("start_scan", "scan", "sweep", "follow", "enrich", "escape")
"""The modes its steps are counted under (``escape``: collision recovery while following)."""

EXPLORER = ExplorerEntry(
    "directions",
    DirectionsConfig,
    "drivenav.agent.explorers.drive_nav.explorer:DirectionsExplorer",
    "DRIVE-Nav: persistent directions, inspection events, one reasoner decision among the forward directions",
    counters=COUNTERS,
    activities=ACTIVITIES,
)
