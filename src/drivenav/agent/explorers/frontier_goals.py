"""Driving to a chosen frontier point, as the frontier-choosing explorers do (the greedy baseline, VLFM, ApexNav): the
planner's step along the weighted-FMM path to the frontier point, goals the planner could not reach skipped for a
while, and a new segment (revisit metric, Sec. V-C) when the explorer switches to a different frontier, not when
its frontier recedes.

An explorer's step with it: :meth:`FrontierGoals.open_paths` (STOP ``no_frontier`` when none is left), the goal
kept (:meth:`~FrontierGoals.kept_goal`) or a new one chosen by the method's own rule among
:meth:`~FrontierGoals.far_enough` and set by :meth:`~FrontierGoals.new_goal`, then :meth:`~FrontierGoals.drive`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.context import Point, StepContext
from drivenav.agent.handles import StepHandles
from drivenav.directions.tracking import waypoints_coincide
from drivenav.directions.types import FrontierPath
from drivenav.inspection import turn_toward
from drivenav.types import Action, Observation


@dataclass
class FrontierGoals:
    """An episode's frontier goals: the goals the planner could not reach, each with the step until which it is
    skipped (``agent.blacklist_steps``), the cells of the frontier headed for, and how many goals were skipped.
    ``min_goal_distance``: a new choice considers frontier points at least this far (metres; all if none is)."""

    min_goal_distance: float
    failed_goals: list[tuple[Point, int]] = field(default_factory=list)
    goal_frontier: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 2)))
    skipped: int = 0

    def open_paths(self, handles: StepHandles, ctx: StepContext) -> list[FrontierPath]:
        """This step's frontier paths, less those ending near a goal that failed within ``blacklist_steps``."""
        reach = self.min_goal_distance
        self.failed_goals = [(g, until) for g, until in self.failed_goals if until >= handles.step]
        return [
            p
            for p in ctx.result.paths.values()
            if not any(math.dist(p.target, g) < reach for g, _ in self.failed_goals)
        ]

    def kept_goal(self, handles: StepHandles, paths: list[FrontierPath]) -> FrontierPath | None:
        """The path to the frontier point nearest the current goal (``state.goal``), if one lies within the merge
        tolerance: the goal is kept while its frontier is there."""
        goal = handles.state.goal
        if goal is None:
            return None
        tolerance = handles.tuning.paper.directions.merge_tolerance
        current = [p for p in paths if math.dist(p.target, goal) <= tolerance]
        return min(current, key=lambda p: math.dist(p.target, goal)) if current else None

    def far_enough(self, paths: list[FrontierPath]) -> list[FrontierPath]:
        """The paths at least ``min_goal_distance`` long (all of them if none is): the goals a new choice considers."""
        return [p for p in paths if p.travel_time >= self.min_goal_distance] or paths

    def drive(self, handles: StepHandles, observation: Observation, ctx: StepContext, chosen: FrontierPath) -> Action:
        """The planner's next step along ``chosen``'s path to its frontier point; a goal it cannot reach is skipped
        for ``blacklist_steps`` (the goal is cleared) and the robot turns toward its bearing meanwhile."""
        state = handles.state
        state.goal = chosen.target
        action = state.planner.act(chosen.path, ctx.pose, observation.collided, ctx.free)
        if action is not None:
            return action
        self.failed_goals.append((chosen.target, handles.step + handles.tuning.config.blacklist_steps))
        self.skipped += 1
        state.goal = None
        return turn_toward(ctx.pose.yaw, chosen.bearing, handles.tuning.turn) or Action.TURN_LEFT

    def new_goal(
        self, handles: StepHandles, ctx: StepContext, chosen: FrontierPath, fresh_planner: bool = False
    ) -> bool:
        """``chosen`` is the explorer's new goal: on another frontier than the one headed for so far, a segment
        starts and the planner forgets its escape plan and stuck history (:meth:`switch_frontier`); True then.
        ``fresh_planner``: the planner forgets them at every new goal, even on the same frontier (the greedy
        baseline's rule)."""
        switched = self.switch_frontier(handles, ctx, chosen.frontier_id)
        if switched or fresh_planner:
            handles.state.planner.reset()
        return switched

    def switch_frontier(self, handles: StepHandles, ctx: StepContext, frontier_id: int) -> bool:
        """A new goal starts a segment unless it lies on the frontier headed for so far (the same frontier, receded
        by at most one forward step beyond the merge tolerance); True when it started one."""
        points = next(f.points for f in ctx.frontiers if f.frontier_id == frontier_id)
        tolerance = handles.tuning.paper.directions.merge_tolerance + handles.tuning.sim.forward_step
        switched = not waypoints_coincide(points, self.goal_frontier, tolerance)
        if switched:
            handles.start_segment()
        self.goal_frontier = points
        return switched
