"""The greedy frontier baseline (``nearest-frontier``, ``explorer.name=greedy``; paper Table II): no views, no
reasoner while it explores.

It heads for the nearest frontier point -- least weighted-FMM travel time, at least ``min_goal_distance`` away --
and keeps it until it is explored or cannot be reached; a goal the planner cannot reach is skipped for
``blacklist_steps`` (:class:`~drivenav.agent.explorers.frontier_goals.FrontierGoals`). A new segment (revisit
metric, Sec. V-C) starts when it switches to a different frontier, not when its frontier recedes.

It opens like DRIVE-Nav: the 360 deg start scan, then one reasoner decision among the directions (with no views)
whose first step it takes, and whose frontier point is its first goal (DRIVE-Nav's modes,
:mod:`drivenav.agent.explorers.drive_nav`, on a memory of its own). The target approach and the stops are the
body's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from drivenav.agent.context import StepContext
from drivenav.agent.explorer import Explorer, ExplorerSetup
from drivenav.agent.explorers.drive_nav.config import DirectionsConfig
from drivenav.agent.explorers.drive_nav.explorer import MODES, begin_directions
from drivenav.agent.explorers.drive_nav.memory import Phase
from drivenav.agent.explorers.frontier_goals import FrontierGoals
from drivenav.agent.explorers.greedy.config import GreedyConfig
from drivenav.agent.handles import StepHandles
from drivenav.directions.types import FrontierPath
from drivenav.types import Action, Observation


@dataclass(frozen=True)
class GreedyCounters:
    """The greedy baseline's episode: its opening decision (``decisions``, by trigger) and the frontier goals it
    skipped because the planner could not reach them."""

    decisions: dict[str, int] = field(default_factory=dict)
    goals_skipped: int = 0


class GreedyExplorer(Explorer):
    """The nearest frontier (module docstring)."""

    def __init__(self, setup: ExplorerSetup) -> None:
        if not isinstance(setup.config, GreedyConfig):
            raise TypeError(f"the greedy explorer takes a GreedyConfig, not {type(setup.config).__name__}")
        self.opening = begin_directions(setup, DirectionsConfig())
        self.goals = FrontierGoals(setup.config.min_goal_distance)

    def begin(self, handles: StepHandles) -> None:
        self.opening.scan.begin(handles)

    def act(self, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
        """The opening's scan and decision, then the next step toward the nearest frontier point; STOP when no
        frontier is left to go to."""
        if self.opening.phase is not Phase.FOLLOW:
            return MODES[self.opening.phase](self.opening, handles, observation, ctx)
        paths = self.goals.open_paths(handles, ctx)
        if not paths:
            return handles.stop("no_frontier")
        chosen = self.goals.kept_goal(handles, paths)
        if chosen is None:
            chosen = self._new_goal(handles, ctx, paths)
        return self.goals.drive(handles, observation, ctx, chosen)

    def resume(self, handles: StepHandles) -> None:
        self.opening.enter(handles, Phase.FOLLOW)

    def activity(self, escaping: bool) -> str:
        return self.opening.activity(escaping)

    def counters(self) -> GreedyCounters:
        decisions = dict(sorted(self.opening.counts.decisions.items()))
        return GreedyCounters(decisions, self.goals.skipped)

    def _new_goal(self, handles: StepHandles, ctx: StepContext, paths: list[FrontierPath]) -> FrontierPath:
        """The nearest frontier point at least ``min_goal_distance`` away (the nearest of all if none is)."""
        chosen = min(self.goals.far_enough(paths), key=lambda p: p.travel_time)
        self.goals.new_goal(handles, ctx, chosen, fresh_planner=True)
        return chosen
