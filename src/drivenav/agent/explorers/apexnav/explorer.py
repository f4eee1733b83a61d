"""ApexNav's adaptive exploration (Zhang et al., RA-L 2025; code Robotics-STAR-Lab/ApexNav,
``exploration_manager.cpp``), written from the method's facts on our agent body; the constants are
:class:`~drivenav.agent.explorers.apexnav.config.ApexnavConfig`'s.

* Value map (``value_map2d.cpp``): every step the image-text scorer scores the frame against "Seems like there is a
  {room} or a {target} ahead?" (the room the reasoner named for the category, :class:`CategoryHints`; "Seems like
  there is a {target} ahead?" for "everywhere"), and the score is fused into the cells the frame's ray cast saw
  free (:meth:`~drivenav.mapping.value_map.ValueMap.update_rays`: VLFM's fusion, bare ``cos^2`` confidence, no
  0.35 drop).
* Start: one turn in place (twelve 30 deg turns). ApexNav turns twice, looking down and then level
  (``FSMCallback``); our camera does not tilt.
* Each decision (``planNextBestPoint``, ``hybridExplorePolicy``): the reachable frontiers that are not dormant are
  scored (:func:`~drivenav.agent.explorers.apexnav.frontiers.frontier_score`) and their statistic picks the mode.
  Semantic: the high-value frontiers, ranked by value (ties within ``value_tie``, then by path), are ordered by an
  open asymmetric TSP over path lengths (:mod:`~drivenav.agent.explorers.apexnav.tsp`) and the tour's first is the
  goal. Geometric: the frontier of the shortest path. The frontier headed for is kept while the frontiers do not
  change (none renewed, :mod:`~drivenav.agent.explorers.apexnav.frontiers`).
* Dormant frontiers (``dormantSeenFrontiers``): a frontier whose centre the robot sees (within ``dormant_fov_deg``
  of its heading, ``dormant_range`` away, no obstacle cell between) and which is still a frontier cannot be
  resolved by looking; so is the frontier headed for once the robot is within ``reached_radius`` of its end or has
  decided ``held_replans`` times without moving. Dormant frontiers are goals only when no other is reachable.
  ApexNav's rule for fewer than 30 unknown cells behind a frontier is our mapper's: it drops frontiers whose
  unexplored pocket is under 1.5 m^2.
* With no frontier to go to: the object of highest target confidence, even below the category's threshold
  (:meth:`~drivenav.agent.target.TargetSearch.settle`, ApexNav's "suspicious" target), then the dormant frontiers,
  then STOP.
* Paths are our weighted-FMM paths (``ctx.result.paths``; between frontiers
  :meth:`~drivenav.directions.pipeline.DirectionPipeline.travel_times`) where ApexNav plans with A* under a 10 ms
  budget, and our :class:`~drivenav.agent.planner.LocalPlanner` drives them where ApexNav scores 12 headings.

Detection and its fusion, the approach and STOP are the body's, switched to ApexNav's rules by the method's preset
(``agent.fusion``, ``agent.stop_in_view``).
"""

from __future__ import annotations

import functools
import math
import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivenav.agent import approach
from drivenav.agent.context import Point, StepContext
from drivenav.agent.explorer import Explorer, ExplorerSetup
from drivenav.agent.explorers.apexnav.config import ApexnavConfig
from drivenav.agent.explorers.apexnav.frontiers import (
    FrontierCells,
    Statistic,
    blocked_cells,
    centroids,
    high_value,
    piece_score,
)
from drivenav.agent.explorers.apexnav.tsp import cost_matrix, open_tour
from drivenav.agent.explorers.frontier_goals import FrontierGoals
from drivenav.agent.explorers.full_scan import FullScan
from drivenav.agent.handles import StepHandles
from drivenav.directions.types import FrontierPath
from drivenav.inspection import signed_offset
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.mapping.value_map import ValueMap, ValueMapConfig
from drivenav.semantics.protocols import EVERYWHERE, CategoryHints, ImageTextScorer, ModelCall, ScorePrompt
from drivenav.types import Action, Observation


@dataclass(frozen=True)
class ApexnavCounters:
    """ApexNav's episode: its decisions by mode (``semantic``, ``geometric``, ``dormant``: among dormant frontiers
    only), the TSPs solved (three or more high-value frontiers), the frontiers made dormant, the objects taken below
    the threshold with nothing left to explore, and the frontier goals the planner could not reach."""

    decisions: dict[str, int] = field(default_factory=dict)
    tsp_solves: int = 0
    dormant_frontiers: int = 0
    settled: int = 0
    goals_skipped: int = 0


class ApexnavExplorer(Explorer):
    """ApexNav's value map, mode switch, TSP and dormant frontiers (module docstring)."""

    uses_scorer = True
    uses_hints = True

    def __init__(self, setup: ExplorerSetup) -> None:
        if not isinstance(setup.config, ApexnavConfig):
            raise TypeError(f"the apexnav explorer takes an ApexnavConfig, not {type(setup.config).__name__}")
        if setup.scorer is None:
            raise ValueError("the apexnav explorer needs an image-text scorer (models.scorer)")
        config = self.config = setup.config
        self.scorer: ImageTextScorer = setup.scorer
        self.scorer.begin_episode(setup.truth)
        room = (setup.hints or CategoryHints.unknown()).room
        anywhere = room == EVERYWHERE
        self.prompt = ScorePrompt(config.prompt_anywhere if anywhere else config.prompt, "" if anywhere else room)
        mapper = setup.mapper
        rule = ValueMapConfig(min_confidence=config.min_confidence, decision_threshold=config.decision_threshold)
        self.value_map = ValueMap(mapper.grid, mapper.config.max_depth, rule)
        self.resolution = mapper.config.resolution
        self.goals = FrontierGoals(0.0)
        self.scan = FullScan.ahead(setup.tuning)
        self.score: float | None = None
        self.dormant = FrontierCells([])  # the cells of the dormant frontiers
        self.before: FrontierCells | None = None  # the frontiers at the last decision (None: decide afresh)
        self.heading = FrontierCells([])  # the cells of the frontier headed for
        self.held = 0
        self.position: Point | None = None
        self.pieces: dict[bytes, NDArray[np.float64]] = {}  # the piece centroids of the frontiers scored last
        self.decisions: Counter[str] = Counter()
        self.tsp_solves = self.dormant_marked = self.settled = 0

    def begin(self, handles: StepHandles) -> None:
        self.scan.begin(handles)

    def observe(
        self, handles: StepHandles, observation: Observation, ctx: StepContext, timings: dict[str, float]
    ) -> None:
        """Score the frame with ApexNav's text, then fuse the score into the cells the frame saw free (the scorer and
        the map update timed apart)."""
        start = time.perf_counter()
        self.score = self.scorer.score(handles.host.goal_text, observation, self.prompt)
        timings["scorer"] = _ms_since(start)
        mark = time.perf_counter()
        mapper = handles.state.mapper
        self.value_map.follow(mapper.grid)
        rays = mapper.last_rays
        if rays is not None and rays.pose == observation.pose:
            self.value_map.update_rays(self.score, rays, observation.intrinsics)
        timings["value_map"] = _ms_since(mark)

    def act(self, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
        """The start turn, then the next step toward the chosen frontier (module docstring)."""
        turn = self.scan.act(handles)
        if turn is not None:
            return turn
        cells = FrontierCells.of(ctx.frontiers, self.resolution)
        dormant = self._dormancy(ctx, cells)
        index = {f.frontier_id: i for i, f in enumerate(ctx.frontiers)}
        paths = self.goals.open_paths(handles, ctx)
        live = [p for p in paths if not dormant[index[p.frontier_id]]]
        if not live:
            if handles.state.search.settle(handles.trace):
                self.settled += 1
                approach.track_target(handles)
                if handles.state.approaching:
                    return handles.policy(observation, ctx)
            if not paths:
                return handles.stop("no_frontier")
        chosen = self._kept(cells, index, live or paths)
        if chosen is None:
            chosen = self._decide(handles, ctx, live) if live else self._nearest(paths, "dormant")
            self.before = cells
            self.heading = cells.pick([index[chosen.frontier_id]])
            self.goals.new_goal(handles, ctx, chosen)
        self._watch(ctx, chosen, cells.pick([index[chosen.frontier_id]]))
        action = self.goals.drive(handles, observation, ctx, chosen)
        if handles.state.goal is None:  # the planner could not reach it: decide afresh next step
            self.before = None
        return action

    def resume(self, handles: StepHandles) -> None:
        self.scan.end(handles)
        self.before = None

    def activity(self, escaping: bool) -> str:
        return self.scan.activity(escaping)

    def counters(self) -> ApexnavCounters:
        decisions = dict(sorted(self.decisions.items()))
        return ApexnavCounters(decisions, self.tsp_solves, self.dormant_marked, self.settled, self.goals.skipped)

    def model_calls(self) -> list[ModelCall]:
        return list(self.scorer.calls)

    def frame_score(self) -> float | None:
        return self.score

    # ----------------------------------------------------------------- decisions

    def _kept(self, cells: FrontierCells, index: dict[int, int], goals: list[FrontierPath]) -> FrontierPath | None:
        """The frontier headed for, while the frontiers are those of the last decision and it is among ``goals``."""
        before = self.before
        if before is None or len(cells) != len(before) or not len(self.heading):
            return None
        same = cells.matches(before, self.config.frontier_changed)
        if not (same.any(axis=1).all() and same.any(axis=0).all()):
            return None
        heading = cells.matches(self.heading, self.config.frontier_changed)[:, 0]
        return next((p for p in goals if heading[index[p.frontier_id]]), None)

    def _decide(self, handles: StepHandles, ctx: StepContext, live: list[FrontierPath]) -> FrontierPath:
        """Semantic or geometric mode by the scores' statistic (module docstring)."""
        config = self.config
        by_id = {f.frontier_id: f for f in ctx.frontiers}
        scores = self._scores([by_id[p.frontier_id] for p in live], ctx.snapshot)
        statistic = Statistic.of(scores)
        if not statistic.semantic(config.sigma_threshold, config.ratio_threshold):
            return self._nearest(live, "geometric")
        kept = set(high_value(scores, statistic, config.ratio_threshold, config.max_to_mean_percentage))
        ranked = [i for i in sorted(range(len(live)), key=functools.cmp_to_key(self._order(live, scores))) if i in kept]
        self.decisions["semantic"] += 1
        return live[ranked[self._tour(handles, [live[i] for i in ranked])]]

    def _scores(self, frontiers: list[Frontier], snapshot: MapSnapshot) -> NDArray[np.float64]:
        """Each frontier's score (its best piece's); a frontier's pieces are split once and kept while it lasts."""
        if self.value_map.grid != snapshot.grid:
            self.value_map.follow(snapshot.grid)
        config, value, blocked = self.config, self.value_map.value, blocked_cells(snapshot)
        known, self.pieces = self.pieces, {}
        scores = []
        for frontier in frontiers:
            signature = frontier.points.tobytes()
            centres = known.get(signature)
            if centres is None:
                centres = centroids(frontier.points, config.piece_radius)
            self.pieces[signature] = centres
            scores.append(piece_score(centres, value, blocked, snapshot.grid, config.score_half_width))
        return np.array(scores)

    def _order(self, live: list[FrontierPath], scores: NDArray[np.float64]) -> functools.partial[int]:
        """ApexNav's frontier order: higher value first, values within ``value_tie`` equal, then shorter path."""
        return functools.partial(_compare, live, scores.tolist(), self.config.value_tie)

    def _tour(self, handles: StepHandles, ranked: list[FrontierPath]) -> int:
        """The index in ``ranked`` of the first frontier of the open ATSP tour over them."""
        config = self.config
        targets = [p.target for p in ranked]
        between = np.full((len(ranked), len(ranked)), np.inf)
        if len(ranked) > 2:  # two frontiers need no lengths between them (tsp.open_tour)
            between[:-1] = handles.state.pipeline.travel_times(targets[:-1], targets)
            self.tsp_solves += 1
        from_robot = np.array([p.travel_time for p in ranked])
        matrix = cost_matrix(from_robot, between, config.tsp_unreachable, config.tsp_diagonal)
        return open_tour(matrix, config.tsp_scale, config.tsp_solutions)[0] - 1

    def _nearest(self, paths: list[FrontierPath], mode: str) -> FrontierPath:
        """The frontier of the shortest path (``findClosestFrontierPolicy``; the first of equals)."""
        self.decisions[mode] += 1
        return min(paths, key=lambda p: p.travel_time)

    # ----------------------------------------------------------------- dormant frontiers

    def _dormancy(self, ctx: StepContext, cells: FrontierCells) -> NDArray[np.bool_]:
        """Which of this step's frontiers are dormant: those matching a dormant one (the others forgotten), then
        those seen in clear view yet still frontiers (made dormant now)."""
        changed = self.config.frontier_changed
        dormant = np.zeros(len(cells), dtype=np.bool_)
        if len(self.dormant):
            same = cells.matches(self.dormant, changed)
            dormant |= same.any(axis=1)
            self.dormant = self.dormant.pick([j for j in range(len(self.dormant)) if same[:, j].any()])
        for i, frontier in enumerate(ctx.frontiers):
            if not dormant[i] and self._in_clear_view(frontier.waypoint, ctx):
                dormant[i] = True
                self._make_dormant(cells.pick([i]))
        return dormant

    def _in_clear_view(self, point: Point, ctx: StepContext) -> bool:
        pose, config = ctx.pose, self.config
        distance = math.dist((pose.x, pose.y), point)
        if distance > config.dormant_range:
            return False
        bearing = math.atan2(point[1] - pose.y, point[0] - pose.x)
        if abs(signed_offset(bearing, pose.yaw)) > math.radians(config.dormant_fov_deg):
            return False
        return _clear(ctx.snapshot, (pose.x, pose.y), point)

    def _watch(self, ctx: StepContext, chosen: FrontierPath, heading: FrontierCells) -> None:
        """Make the frontier headed for dormant once reached and still there, or held without motion."""
        config, here = self.config, (ctx.pose.x, ctx.pose.y)
        moved = self.position is None or math.dist(here, self.position) >= config.moved
        self.position = here
        self.held = 0 if moved else self.held + 1
        if math.dist(here, chosen.target) < config.reached_radius or self.held >= config.held_replans:
            self._make_dormant(heading)
            self.held = 0
            self.before = None

    def _make_dormant(self, frontier: FrontierCells) -> None:
        self.dormant = self.dormant.plus(frontier)
        self.dormant_marked += 1


def _compare(live: list[FrontierPath], scores: list[float], tie: float, a: int, b: int) -> int:
    if abs(scores[a] - scores[b]) >= tie:
        return -1 if scores[a] > scores[b] else 1
    return (live[a].travel_time > live[b].travel_time) - (live[a].travel_time < live[b].travel_time)


def _clear(snapshot: MapSnapshot, start: Point, end: Point) -> bool:
    """No obstacle cell on the segment (sampled every half cell)."""
    grid = snapshot.grid
    steps = max(1, math.ceil(math.dist(start, end) / (0.5 * grid.resolution)))
    t = np.linspace(0.0, 1.0, steps + 1)
    points = np.stack([start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1])], axis=1)
    cells = grid.world_to_cell(points)
    rows, cols = snapshot.obstacle.shape
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < rows) & (cells[:, 1] >= 0) & (cells[:, 1] < cols)
    return not bool(snapshot.obstacle[cells[inside, 0], cells[inside, 1]].any())


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0
