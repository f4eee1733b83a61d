"""The greedy frontier baseline (``nearest-frontier``, ``use_reasoner=False``; paper Table II): the follow mode
without directions, views or reasoner.

It heads for the nearest frontier point -- least weighted-FMM travel time, at least ``min_goal_distance`` away --
and keeps it until it is explored or cannot be reached; a goal the planner cannot reach is skipped for
``blacklist_steps``. A new segment (revisit metric, Sec. V-C) starts when it switches to a different frontier,
not when its frontier recedes. The start scan, the target approach and the stops are those of DRIVE-Nav.
VLFM's frontier choice (:mod:`drivenav.agent.vlfm`) drives, skips and starts segments with the same functions.
"""

from __future__ import annotations

import math

from drivenav.agent.context import StepContext
from drivenav.agent.loop import Loop
from drivenav.directions.tracking import waypoints_coincide
from drivenav.directions.types import FrontierPath
from drivenav.inspection import turn_toward
from drivenav.types import Action, Observation


def act(loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """The next step toward the greedy goal; STOP when no frontier is left to go to."""
    paths = open_paths(loop, ctx)
    if not paths:
        return loop.stop("no_frontier")
    chosen = _keep_goal(loop, paths)
    if chosen is None:
        chosen = _new_goal(loop, ctx, paths)
    return drive(loop, observation, ctx, chosen)


def drive(loop: Loop, observation: Observation, ctx: StepContext, chosen: FrontierPath) -> Action:
    """The planner's next step along ``chosen``'s path to its frontier point; a goal it cannot reach is skipped
    for ``blacklist_steps`` (the goal is cleared) and the robot turns toward its bearing meanwhile."""
    state = loop.state
    state.goal = chosen.target
    action = state.planner.act(chosen.path, ctx.pose, observation.collided, ctx.free)
    if action is not None:
        return action
    state.greedy.failed_goals.append((chosen.target, loop.step + loop.tuning.config.blacklist_steps))
    state.goal = None
    return turn_toward(ctx.pose.yaw, chosen.bearing, loop.tuning.turn) or Action.TURN_LEFT


def open_paths(loop: Loop, ctx: StepContext) -> list[FrontierPath]:
    """This step's frontier paths, less those ending near a goal that failed within ``blacklist_steps``."""
    memory, reach = loop.state.greedy, loop.tuning.config.min_goal_distance
    memory.failed_goals = [(g, until) for g, until in memory.failed_goals if until >= loop.step]
    return [
        p for p in ctx.result.paths.values() if not any(math.dist(p.target, g) < reach for g, _ in memory.failed_goals)
    ]


def far_enough(loop: Loop, paths: list[FrontierPath]) -> list[FrontierPath]:
    """The paths at least ``min_goal_distance`` long (all of them if none is): the goals a new choice considers."""
    return [p for p in paths if p.travel_time >= loop.tuning.config.min_goal_distance] or paths


def _keep_goal(loop: Loop, paths: list[FrontierPath]) -> FrontierPath | None:
    """The path to the frontier point nearest the current goal, if one lies within the merge tolerance."""
    goal = loop.state.goal
    if goal is None:
        return None
    tolerance = loop.tuning.paper.directions.merge_tolerance
    current = [p for p in paths if math.dist(p.target, goal) <= tolerance]
    return min(current, key=lambda p: math.dist(p.target, goal)) if current else None


def _new_goal(loop: Loop, ctx: StepContext, paths: list[FrontierPath]) -> FrontierPath:
    """The nearest frontier point at least ``min_goal_distance`` away (the nearest of all if none is)."""
    chosen = min(far_enough(loop, paths), key=lambda p: p.travel_time)
    switch_frontier(loop, ctx, chosen.frontier_id)
    loop.state.planner.reset()
    return chosen


def switch_frontier(loop: Loop, ctx: StepContext, frontier_id: int) -> bool:
    """A new goal starts a segment unless it lies on the frontier headed for so far (the same frontier, receded
    by at most one forward step beyond the merge tolerance); True when it started one."""
    memory = loop.state.greedy
    points = next(f.points for f in ctx.frontiers if f.frontier_id == frontier_id)
    tolerance = loop.tuning.paper.directions.merge_tolerance + loop.tuning.sim.forward_step
    switched = not waypoints_coincide(points, memory.goal_frontier, tolerance)
    if switched:
        loop.start_segment()
    memory.goal_frontier = points
    return switched
