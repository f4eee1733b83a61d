"""VLFM's exploration (``vlfm``, ``explorer.name=vlfm``; Yokoyama et al., "VLFM: Vision-Language Frontier Maps for
Zero-Shot Semantic Navigation", ICRA 2024; code bdaiinstitute/vlfm): the frontier chosen on a value map
(:mod:`drivenav.mapping.value_map`) instead of by distance.

* Every step the image-text scorer scores the frame against the goal and the score is spread over the value map
  (``vlfm/policy/base_objectnav_policy.py`` ``_update_value_map``).
* Initial turn in place (``vlfm/policy/habitat_policies.py`` ``HabitatMixin._initialize``: twelve 30 deg left
  turns), then straight into the frontier choice -- no reasoner decision.
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
  (:class:`~drivenav.agent.explorers.frontier_goals.FrontierGoals`, as the greedy baseline does): a new choice
  considers only frontiers at least ``min_goal_distance`` away (all if none is), an unreachable goal is skipped
  for ``blacklist_steps``, and a segment (revisit metric, Sec. V-C) starts when the frontier headed for changes.

Detection, the object map, the approach and STOP are the body's (enrichment and verification off).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from drivenav.agent.context import Point, StepContext
from drivenav.agent.explorer import Explorer, ExplorerSetup
from drivenav.agent.explorers.frontier_goals import FrontierGoals
from drivenav.agent.explorers.full_scan import FullScan
from drivenav.agent.explorers.vlfm.config import VlfmConfig
from drivenav.agent.handles import StepHandles
from drivenav.directions.types import FrontierPath
from drivenav.mapping.types import Frontier
from drivenav.mapping.value_map import ValueMap, ValueMapConfig
from drivenav.semantics.protocols import ImageTextScorer, ModelCall
from drivenav.types import Action, Observation

Ranked = list[tuple[FrontierPath, Point, float]]
"""Frontier paths with their frontier point and value, best first."""


@dataclass
class ValueMemory:
    """What VLFM's frontier choice remembers (``itm_policy.py`` ``BaseITMPolicy``): the frontier point pursued and
    its value when chosen (``_last_frontier``, ``_last_value``), and every (robot position, frontier point, top two
    values) choice made (``AcyclicEnforcer``'s history)."""

    point: Point | None = None
    value: float = float("-inf")
    history: set[tuple[Point, Point, tuple[float, ...]]] = field(default_factory=set)


@dataclass(frozen=True)
class VlfmCounters:
    """VLFM's episode: new frontier choices (the pursued one given up or gone), those where every frontier had been
    chosen from the same place with the same top values (the acyclic enforcer's farthest-point fallback), and the
    frontier goals skipped because the planner could not reach them."""

    new_choices: int = 0
    acyclic_fallbacks: int = 0
    goals_skipped: int = 0


class VlfmExplorer(Explorer):
    """VLFM's value map and frontier choice (module docstring)."""

    uses_scorer = True

    def __init__(self, setup: ExplorerSetup) -> None:
        if not isinstance(setup.config, VlfmConfig):
            raise TypeError(f"the vlfm explorer takes a VlfmConfig, not {type(setup.config).__name__}")
        if setup.scorer is None:
            raise ValueError("the vlfm explorer needs an image-text scorer (models.scorer)")
        self.config = setup.config
        self.scorer: ImageTextScorer = setup.scorer
        self.scorer.begin_episode(setup.truth)
        mapper = setup.mapper
        self.value_map = ValueMap(mapper.grid, mapper.config.max_depth, setup.config)
        self.memory = ValueMemory()
        self.goals = FrontierGoals(setup.config.min_goal_distance)
        self.scan = FullScan.ahead(setup.tuning)
        self.new_choices = 0
        self.fallbacks = 0

    def begin(self, handles: StepHandles) -> None:
        self.scan.begin(handles)

    def observe(
        self, handles: StepHandles, observation: Observation, ctx: StepContext, timings: dict[str, float]
    ) -> None:
        """Score the frame against the goal, then spread the score over the value map (on the mapper's grid, which
        may have grown this step); the scorer and the map update are timed apart."""
        start = time.perf_counter()
        score = self.scorer.score(handles.host.goal_text, observation)
        timings["scorer"] = _ms_since(start)
        mark = time.perf_counter()
        self.value_map.follow(handles.state.mapper.grid)
        self.value_map.update(score, observation.pose, observation.depth, observation.intrinsics)
        timings["value_map"] = _ms_since(mark)

    def act(self, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
        """The initial turn in place, then the next step toward the frontier of highest value; STOP when no frontier
        is left."""
        turn = self.scan.act(handles)
        if turn is not None:
            return turn
        paths = self.goals.open_paths(handles, ctx)
        if not paths:
            return handles.stop("no_frontier")
        chosen = self._choose(handles, ctx, paths)
        action = self.goals.drive(handles, observation, ctx, chosen)
        if handles.state.goal is None:  # the planner could not reach it: choose afresh next step
            self.memory.point = None
        return action

    def resume(self, handles: StepHandles) -> None:
        self.scan.end(handles)

    def activity(self, escaping: bool) -> str:
        return self.scan.activity(escaping)

    def counters(self) -> VlfmCounters:
        return VlfmCounters(self.new_choices, self.fallbacks, self.goals.skipped)

    def model_calls(self) -> list[ModelCall]:
        return list(self.scorer.calls)

    def _choose(self, handles: StepHandles, ctx: StepContext, paths: list[FrontierPath]) -> FrontierPath:
        """VLFM's choice among ``paths`` (module docstring), remembered; a new frontier starts a segment."""
        memory, config = self.memory, self.config
        ranked = rank(self.value_map, ctx.frontiers, paths)
        top_two = tuple(v for _, _, v in ranked[:2])
        here = (ctx.pose.x, ctx.pose.y)
        index = kept(ranked, memory, config)
        if index is None:
            candidates = {p.frontier_id for p in self.goals.far_enough(paths)}
            fresh = [item for item in ranked if item[0].frontier_id in candidates]
            self.new_choices += 1
            self.fallbacks += all((here, point, top_two) in memory.history for _, point, _ in fresh)
            path, point, value = fresh[best_acyclic(fresh, memory, here, top_two)]
            self.goals.new_goal(handles, ctx, path)
        else:
            path, point, value = ranked[index]
        memory.history.add((here, point, top_two))
        memory.point, memory.value = point, value
        return path


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


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0
