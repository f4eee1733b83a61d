"""The farthest-frontier explorer: after a turn in place (the start scan,
:class:`~drivenav.agent.explorers.full_scan.FullScan`), it heads for the frontier point with the
largest weighted-FMM travel time (no farther than ``max_travel_time``) and keeps it until it is explored or cannot be
reached, driving there as drivenav's greedy baseline does
(:class:`~drivenav.agent.explorers.frontier_goals.FrontierGoals`). Each new goal is a trace event of its own
(:class:`FarthestGoal`); the episode's counters are :class:`FarthestCounters` (both declared by its entry,
:mod:`drivenav_example.config`). The target search, the approach and STOP are the agent body's."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from drivenav.agent.context import StepContext
from drivenav.agent.explorer import Explorer, ExplorerSetup
from drivenav.agent.explorers.frontier_goals import FrontierGoals
from drivenav.agent.explorers.full_scan import FullScan
from drivenav.agent.handles import StepHandles
from drivenav.agent.trace import Event
from drivenav.directions.types import FrontierPath
from drivenav.types import Action, Observation
from drivenav_example.config import FarthestConfig


@dataclass(frozen=True)
class FarthestGoal(Event):
    """A new goal (at ``step``): its frontier, its point ((x, y) m, the episode's frame) and the travel time to it."""

    frontier_id: int
    target: tuple[float, float]
    travel_time: float
    kind: ClassVar[str] = "farthest_goal"


@dataclass(frozen=True)
class FarthestCounters:
    """One episode's goals: how many frontier points it chose, the longest travel time to one (m) and how many it
    skipped as unreachable."""

    goals_chosen: int = 0
    longest_goal: float = 0.0
    goals_skipped: int = 0


class FarthestExplorer(Explorer):
    """The farthest frontier point (module docstring); one instance per episode, its memory."""

    def __init__(self, setup: ExplorerSetup) -> None:
        if not isinstance(setup.config, FarthestConfig):
            raise TypeError(f"the farthest explorer takes a FarthestConfig, not {type(setup.config).__name__}")
        self.max_travel_time = setup.config.max_travel_time
        self.goals = FrontierGoals(min_goal_distance=1.0)
        self.scan = FullScan.ahead(setup.tuning)
        self.chosen = 0
        self.longest = 0.0

    def begin(self, handles: StepHandles) -> None:
        self.scan.begin(handles)

    def act(self, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
        turn = self.scan.act(handles)
        if turn is not None:
            return turn
        paths = self.goals.open_paths(handles, ctx)
        if not paths:
            return handles.stop("no_frontier")
        chosen = self.goals.kept_goal(handles, paths) or self._new_goal(handles, ctx, paths)
        return self.goals.drive(handles, observation, ctx, chosen)

    def resume(self, handles: StepHandles) -> None:
        self.scan.end(handles)

    def activity(self, escaping: bool) -> str:
        return self.scan.activity(escaping)

    def counters(self) -> FarthestCounters:
        return FarthestCounters(self.chosen, self.longest, self.goals.skipped)

    def _new_goal(self, handles: StepHandles, ctx: StepContext, paths: list[FrontierPath]) -> FrontierPath:
        """The farthest frontier point within ``max_travel_time`` (the nearest of all if none is)."""
        within = [p for p in self.goals.far_enough(paths) if p.travel_time <= self.max_travel_time]
        chosen = max(within, key=lambda p: p.travel_time) if within else min(paths, key=lambda p: p.travel_time)
        self.goals.new_goal(handles, ctx, chosen)
        (x, y), travel_time = chosen.target, float(chosen.travel_time)
        handles.trace.add(FarthestGoal(handles.step, int(chosen.frontier_id), (float(x), float(y)), travel_time))
        self.chosen += 1
        self.longest = max(self.longest, travel_time)
        return chosen
