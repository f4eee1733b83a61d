"""Everything one episode of the decision loop knows (paper Sec. IV): made when the agent is reset, dropped when
the episode ends, so nothing carries over from one episode to the next.

:class:`Mode` names the loop's five modes (Sec. IV overview): the start scan, the inspection sweep, following a
direction, prompt enrichment and the target approach. :class:`EpisodeState` holds the maps and models the episode
works with and the state the mode handlers (:mod:`drivenav.agent.modes`) share.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.context import Point
from drivenav.agent.counts import EpisodeCounts
from drivenav.agent.planner import LocalPlanner
from drivenav.agent.target import TargetSearch
from drivenav.directions import Direction, DirectionPipeline
from drivenav.inspection import RepresentativeViews
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.value_map import ValueMap
from drivenav.semantics.protocols import ImageTextScorer, Reasoner
from drivenav.types import Action


class Mode(Enum):
    """The mode the loop is in; its value names the steps spent in it (``steps_by_activity``)."""

    SCAN = "scan"
    SWEEP = "sweep"
    FOLLOW = "follow"
    ENRICH = "enrich"
    APPROACH = "approach"


@dataclass
class GreedyMemory:
    """What the greedy baseline (:mod:`drivenav.agent.greedy`) remembers: goals it could not reach, each with the
    step until which it is skipped, and the cells of the frontier it heads for."""

    failed_goals: list[tuple[Point, int]] = field(default_factory=list)
    goal_frontier: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 2)))


@dataclass
class ValueMemory:
    """What VLFM's frontier choice (:mod:`drivenav.agent.vlfm`) remembers (``itm_policy.py`` ``BaseITMPolicy``): the
    frontier point pursued and its value when chosen (``_last_frontier``, ``_last_value``), and every (robot
    position, frontier point, top two values) choice made (``AcyclicEnforcer``'s history)."""

    point: Point | None = None
    value: float = float("-inf")
    history: set[tuple[Point, Point, tuple[float, ...]]] = field(default_factory=set)


@dataclass
class ValueSearch:
    """VLFM's image-text scorer and value map of one episode (the ``vlfm`` method), and its frontier memory."""

    scorer: ImageTextScorer
    value_map: ValueMap
    memory: ValueMemory = field(default_factory=ValueMemory)


@dataclass
class EpisodeState:
    """One episode's maps, models and decision state.

    ``inspected`` holds the labels an inspection event or decision has already covered, ``blacklist`` the
    directions that could not be followed (label -> step until which they are left out), ``selected`` the
    direction followed and ``followed`` that direction as of the previous step; ``previous`` holds the previous
    step's directions and ``gone`` the retired ones with the step they went (Sec. IV-A b). ``event_heading`` is
    the heading when the current inspection event began (Sec. IV-A c). ``descriptions`` and ``enriched`` are the
    reasoner's words on each direction and the directions enrichment has run on (Sec. IV-B); ``target`` is the
    candidate approached (Sec. IV-C) and ``goal`` the point the planner heads for. ``values`` is VLFM's scorer
    and value map (the ``vlfm`` method only).
    """

    mapper: OccupancyMapper
    pipeline: DirectionPipeline
    views: RepresentativeViews
    planner: LocalPlanner
    reasoner: Reasoner
    search: TargetSearch
    scan_turns: int
    mode: Mode = Mode.SCAN
    pending_yaws: list[float] = field(default_factory=list)
    inspected: set[int] = field(default_factory=set)
    blacklist: dict[int, int] = field(default_factory=dict)
    descriptions: dict[int, str] = field(default_factory=dict)
    enriched: set[int] = field(default_factory=set)
    enrich_label: int | None = None
    selected: int | None = None
    followed: Direction | None = None
    previous: dict[int, Direction] = field(default_factory=dict)
    gone: dict[int, tuple[Direction, int]] = field(default_factory=dict)
    event_heading: float = 0.0
    goal: Point | None = None
    target: int | None = None
    detour_steps: int = 0
    greedy: GreedyMemory = field(default_factory=GreedyMemory)
    values: ValueSearch | None = None
    counts: EpisodeCounts = field(default_factory=EpisodeCounts)

    def activity(self, action: Action) -> str:
        """What this step's action was spent on (the steps-by-activity counter): the mode, ``start_scan`` for
        the scan before the first decision, ``escape`` for collision recovery and ``stop``."""
        if action == Action.STOP:
            return "stop"
        if self.mode in (Mode.FOLLOW, Mode.APPROACH) and self.planner.escaping:
            return "escape"
        if self.mode is Mode.SCAN:
            return "scan" if self.counts.decisions else "start_scan"
        return str(self.mode.value)
