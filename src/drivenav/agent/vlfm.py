"""VLFM's exploration (``vlfm``; Yokoyama et al., "VLFM: Vision-Language Frontier Maps for Zero-Shot Semantic
Navigation", ICRA 2024; code bdaiinstitute/vlfm): the follow mode of the ``use_reasoner=False`` baseline with the
frontier chosen on a value map (:mod:`drivenav.mapping.value_map`) instead of by distance.

* Initial turn in place (``vlfm/policy/habitat_policies.py`` ``HabitatMixin._initialize``: twelve 30 deg left
  turns): the start scan's turns (:mod:`drivenav.agent.modes.scan`), then straight into the frontier choice -- no
  reasoner decision.
* Frontier choice (``vlfm/policy/itm_policy.py`` ``BaseITMPolicy._get_best_frontier`` with
  ``ITMPolicyV2._sort_frontiers_by_value``): every frontier is valued at its point (VLFM's frontier midpoint; here
  :attr:`~drivenav.mapping.types.Frontier.waypoint`) by :meth:`~drivenav.mapping.value_map.ValueMap.value_at`
  and ranked by value (ties: the shorter path first). The frontier pursued so far is kept while a frontier point
  lies within ``keep_radius`` of it and that point's value plus ``keep_margin`` exceeds its value when it was
  chosen. Otherwise the best-ranked frontier is taken whose (robot position, frontier point, top two values)
  choice was never made before (``vlfm/policy/utils/acyclic_enforcer.py`` ``AcyclicEnforcer``); when every one
  was, the farthest frontier point from the robot (VLFM's code takes the farthest; its comment says closest).
* Where VLFM drives to the frontier with a learned PointNav policy, we follow the weighted-FMM path to the
  frontier's nearest reachable cell with our :class:`~drivenav.agent.planner.LocalPlanner`
  (:func:`drivenav.agent.greedy.drive`); as in the greedy baseline, a new choice considers only frontiers at least
  ``min_goal_distance`` away (all if none is), an unreachable goal is skipped for ``blacklist_steps``, and a
  segment (revisit metric, Sec. V-C) starts when the frontier headed for changes.

Detection, the object map, the approach and STOP are DRIVE-Nav's (enrichment and verification off).
"""

from __future__ import annotations

import math

from drivenav.agent import greedy
from drivenav.agent.context import Point, StepContext
from drivenav.agent.loop import Loop
from drivenav.agent.modes import scan as start_scan
from drivenav.agent.state import Mode, ValueMemory, ValueSearch
from drivenav.directions.types import FrontierPath
from drivenav.mapping.types import Frontier
from drivenav.mapping.value_map import ValueMap, ValueMapConfig
from drivenav.types import Action, Observation

Ranked = list[tuple[FrontierPath, Point, float]]
"""Frontier paths with their frontier point and value, best first."""


def scan(loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """VLFM's initial turn in place (the start scan's turns), then the value-map frontier choice."""
    if loop.state.scan_turns > 0:
        return start_scan.act(loop, observation, ctx)
    loop.state.mode = Mode.FOLLOW
    return act(loop, observation, ctx)


def act(loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """The next step toward the frontier of highest value (module docstring); STOP when no frontier is left."""
    state = loop.state
    values = _values(loop)
    paths = greedy.open_paths(loop, ctx)
    if not paths:
        return loop.stop("no_frontier")
    chosen = _choose(loop, ctx, values, paths)
    action = greedy.drive(loop, observation, ctx, chosen)
    if state.goal is None:  # the planner could not reach it: choose afresh next step
        values.memory.point = None
    return action


def rank(value_map: ValueMap, frontiers: list[Frontier], paths: list[FrontierPath]) -> Ranked:
    """``paths`` with their frontier's point (of ``frontiers``) and its value on ``value_map``, by value (highest
    first), then by travel time."""
    points = {f.frontier_id: f.waypoint for f in frontiers}
    chosen_points = [points[p.frontier_id] for p in paths]
    scores = value_map.value_at(chosen_points)
    ranked = [(p, q, float(v)) for p, q, v in zip(paths, chosen_points, scores, strict=True)]
    return sorted(ranked, key=lambda item: (-item[2], item[0].travel_time))


def kept(ranked: Ranked, memory: ValueMemory, config: ValueMapConfig) -> int | None:
    """The index in ``ranked`` of the frontier pursued so far, if it is still there and its value has not fallen
    by ``keep_margin`` or more since it was chosen."""
    if memory.point is None or not ranked:
        return None
    last = memory.point
    index = min(range(len(ranked)), key=lambda i: math.dist(ranked[i][1], last))
    if math.dist(ranked[index][1], last) > config.keep_radius:
        return None
    return index if ranked[index][2] + config.keep_margin > memory.value else None


def best_acyclic(ranked: Ranked, memory: ValueMemory, here: Point, top_two: tuple[float, ...]) -> int:
    """The index of the best-ranked frontier not chosen before from ``here`` with the same top two values; the
    farthest from ``here`` when every one was."""
    for index, (_, point, _) in enumerate(ranked):
        if (here, point, top_two) not in memory.history:
            return index
    return max(range(len(ranked)), key=lambda i: math.dist(ranked[i][1], here))


def _choose(loop: Loop, ctx: StepContext, values: ValueSearch, paths: list[FrontierPath]) -> FrontierPath:
    """VLFM's choice among ``paths`` (module docstring), remembered; a new frontier starts a segment."""
    memory, config = values.memory, loop.tuning.config.vlfm
    ranked = rank(values.value_map, ctx.frontiers, paths)
    top_two = tuple(v for _, _, v in ranked[:2])
    here = (ctx.pose.x, ctx.pose.y)
    index = kept(ranked, memory, config)
    if index is None:
        candidates = {p.frontier_id for p in greedy.far_enough(loop, paths)}
        fresh = [item for item in ranked if item[0].frontier_id in candidates]
        path, point, value = fresh[best_acyclic(fresh, memory, here, top_two)]
        if greedy.switch_frontier(loop, ctx, path.frontier_id):
            loop.state.planner.reset()
    else:
        path, point, value = ranked[index]
    memory.history.add((here, point, top_two))
    memory.point, memory.value = point, value
    return path


def _values(loop: Loop) -> ValueSearch:
    values = loop.state.values
    if values is None:
        raise RuntimeError("the vlfm follow mode needs the value map (agent.value_map=true)")
    return values
