"""The DRIVE-Nav decision loop (paper Sec. IV overview and IV-A c), composable into its baselines.

Each step: depth + pose update the maps; one weighted-FMM solve turns frontiers into tracked directions and
gives the path to the current goal; representative views are recorded opportunistically; the grounder looks for
the target. The policy then continues the current mode:

- ``SCAN``: the 360 deg start scan (twelve 30 deg turns), then a reasoner decision;
- ``SWEEP``: an inspection event -- rotate only over the forward-240 deg directions lacking views, then decide;
- ``FOLLOW``: drive toward the farthest frontier point of the selected direction (re-planned each step) until an
  inspection event (new forward directions lacking views) or the direction is gone; a followed direction that
  only got a fresh label (merged with another, or re-found at the same place) is still followed;
- ``ENRICH``: the reasoner sees the target but the grounder does not: face that direction, then prompt
  enrichment (Sec. IV-B);
- ``APPROACH``: drive to the target candidate, verifying it on the way (Sec. IV-C), and STOP within
  ``stop_distance`` once it is accepted. While no mapped free cell leads to it yet, drive through the frontier
  nearest to it; a target that cannot be reached is set aside for a while, never rejected.

Which directions a decision offers the reasoner (Sec. IV-A c; docs/agent.md): after the start scan, every
direction; afterwards only the still-relevant ones (tracked, not blacklisted, with a view) within the forward
240 deg of the heading at the decision (at an inspection event, the heading when it began) -- unless none is
left there (a dead end), when the rear range is offered too.

Config switches give the baselines and ablations: ``use_reasoner=False`` (nearest frontier), ``decision_scan``
(a full 360 deg scan at every decision: ``direction-360``, ``frontier``), ``cluster_span`` 0 (raw frontiers as
candidates), the speed field's ``weighted`` flag and the inspection's ``restrict_forward`` flag.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.base import Agent, DecisionStats, ModelStats
from drivenav.agent.config import AgentConfig
from drivenav.agent.planner import LocalPlanner
from drivenav.agent.target import SearchConfig, TargetSearch
from drivenav.agent.trace import DirectionSelected, InspectionStarted, ScanStarted, ViewCaptured
from drivenav.directions import Direction, DirectionPipeline, DirectionResult
from drivenav.directions.tracking import waypoints_coincide
from drivenav.grid import wrap_angle
from drivenav.inspection import RepresentativeViews, full_scan_turns, needs_inspection, plan_sweep, turn_toward
from drivenav.inspection.sweep import signed_offset, within
from drivenav.mapping.config import MappingConfig, MapTuning
from drivenav.mapping.objects import nearest_point
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import DriveNavConfig
from drivenav.semantics.geometric import GeometricReasoner
from drivenav.semantics.ground_truth import GroundTruthGrounder
from drivenav.semantics.protocols import Candidate, Grounder, Reasoner, Selection, View
from drivenav.types import SEMANTIC, Action, GroundTruth, Observation, Pose, SimConfig

Point = tuple[float, float]


class Mode(Enum):
    SCAN = "scan"
    SWEEP = "sweep"
    FOLLOW = "follow"
    ENRICH = "enrich"
    APPROACH = "approach"


@dataclass
class StepContext:
    """What this step's perception produced (episode frame)."""

    pose: Pose
    snapshot: MapSnapshot
    frontiers: list[Frontier]
    result: DirectionResult
    goal: Point | None
    directions: dict[int, Direction] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.directions = {d.label: d for d in self.result.directions}

    def free(self, x: float, y: float) -> bool:
        """Whether a point is navigable on the robot's map (the planner's line-of-sight test)."""
        row, col = self.snapshot.grid.cell_at(x, y)
        inside = 0 <= row < self.snapshot.navigable.shape[0] and 0 <= col < self.snapshot.navigable.shape[1]
        return bool(inside and self.snapshot.navigable[row, col])

    @property
    def goal_path(self) -> NDArray[np.float64] | None:
        return self.result.goal_paths[0] if self.result.goal_paths else None


class DriveNavAgent(Agent):
    """DRIVE-Nav (``drive-nav``) and, through :class:`AgentConfig`, its baselines."""

    def __init__(
        self,
        sim: SimConfig,
        config: AgentConfig | None = None,
        paper: DriveNavConfig | None = None,
        mapping: MapTuning | None = None,
        name: str = "drive-nav",
        reasoner_factory: Callable[[], Reasoner] = GeometricReasoner,
        grounder_factory: Callable[[], Grounder] = GroundTruthGrounder,
        requires: frozenset[str] = frozenset({SEMANTIC}),
    ) -> None:
        super().__init__(sim)
        self.requires = requires  # what the models read of the world's ground truth (the default grounder: labels)
        self.name = name
        self.config = config or AgentConfig()
        self.paper = paper or DriveNavConfig()
        self.mapping = mapping or MapTuning()
        self._reasoner_factory = reasoner_factory
        self._grounder_factory = grounder_factory
        self._turn = math.radians(sim.turn_angle_deg)
        self._start_maps()

    # ----------------------------------------------------------------- episode set-up

    def reset(self, goal_text: str, seed: int, truth: GroundTruth | None = None) -> None:
        super().reset(goal_text, seed, truth)
        paper = self.paper
        self._start_maps()
        self._planner = LocalPlanner.from_config(self.sim, self.config.planner)
        self._reasoner = self._reasoner_factory()
        self._reasoner.begin_episode(goal_text, truth)
        grounder = self._grounder_factory()
        grounder.begin_episode(truth, seed)
        semantics = paper.semantics
        search = SearchConfig(
            self.config.enrich,
            self.config.verify,
            semantics.enrich_rounds,
            semantics.verify_frames,
            semantics.verify_spacing_steps,
        )
        self._search = TargetSearch(self.sim, search, grounder, self._reasoner)
        self._search.begin(goal_text)
        self._descriptions: dict[int, str] = {}
        self._enriched: set[int] = set()
        self._enrich_label: int | None = None
        self._mode = Mode.SCAN
        self._scan_turns = full_scan_turns(self._turn)
        self._pending_yaws: list[float] = []
        self._inspected: set[int] = set()
        self._blacklist: dict[int, int] = {}
        self._failed_goals: list[tuple[Point, int]] = []  # greedy baseline: (goal, step until which it is skipped)
        self._goal_frontier = np.empty((0, 2))  # greedy baseline: the cells of the frontier it heads for
        self._selected: int | None = None
        self._followed: Direction | None = None  # the selected direction as of the previous step
        self._previous: dict[int, Direction] = {}  # the directions of the previous step
        self._gone: dict[int, tuple[Direction, int]] = {}  # retired directions and the step they went
        self._event_heading = 0.0  # the heading when the current inspection event began
        self._goal: Point | None = None
        self._target: int | None = None
        self._detour_steps = 0
        self._stats = _Counts()
        self.trace.add(ScanStarted(0, self._scan_turns))

    def end_episode(self) -> None:
        """The mapper, the directions pipeline and the views start over: their grids and kept transforms (tens of MB
        on a large floor plan) go before the next scene loads, not after (issue 14: worker memory). Safe before any
        :meth:`reset` (a world that failed to reset the worker's first episode)."""
        super().end_episode()
        self._start_maps()

    def _start_maps(self) -> None:
        """An empty mapper, directions pipeline and set of representative views."""
        self._mapper = OccupancyMapper(MappingConfig.from_sim(self.sim, self.mapping))
        self._pipeline = DirectionPipeline(self.paper)
        self._views = RepresentativeViews(self.paper.inspection.view_tolerance)

    @property
    def model_calls(self) -> int:
        return len(self._reasoner.calls)

    # ----------------------------------------------------------------- one step

    def decide(self, observation: Observation) -> Action:
        timings: dict[str, float] = {}
        start = time.perf_counter()
        self._mapper.update(observation.depth, observation.intrinsics, observation.pose)
        if observation.occupancy is not None and self._mapper.config.fuse_lidar:  # a robot's LiDAR (Sec. V-E)
            self._mapper.fuse_occupancy(observation.occupancy)
        snapshot, frontiers = self._mapper.snapshot(), self._mapper.frontiers()
        timings["mapping"] = _ms_since(start)
        ctx = self._perceive(observation.pose, snapshot, frontiers, self._goal)
        timings.update({f"directions.{k}": v for k, v in ctx.result.timings_ms.items()})
        mark = time.perf_counter()
        self._carry_over(ctx)
        self._record_views(observation, ctx)
        timings["inspection"] = _ms_since(mark)
        mark = time.perf_counter()
        self._search.observe(observation, self.trace)
        self._track_target()
        timings["grounding"] = _ms_since(mark)
        mark = time.perf_counter()
        action = self._policy(observation, ctx)
        self._stats.count_step(action, self._activity(action))
        timings["policy"] = _ms_since(mark)
        timings["total"] = _ms_since(start)
        self.step_timings.append(timings)
        return action

    def _perceive(
        self, pose: Pose, snapshot: MapSnapshot, frontiers: list[Frontier], goal: Point | None
    ) -> StepContext:
        goals = [goal] if goal is not None else []
        result = self._pipeline.update(snapshot, frontiers, (pose.x, pose.y), goals=goals)
        return StepContext(pose, snapshot, frontiers, result, goal)

    def _replan(self, ctx: StepContext, goal: Point) -> StepContext:
        """The same step's perception with a new goal (only at decision steps)."""
        if ctx.goal == goal:
            return ctx
        return self._perceive(ctx.pose, ctx.snapshot, ctx.frontiers, goal)

    def _carry_over(self, ctx: StepContext) -> None:
        """Carry what belongs to a direction over its relabelling (Sec. IV-A b): a merged direction inherits its
        parents' inspected state and best view; the followed direction that lost its label is still followed
        when a fresh label took over its frontiers (a merge, or a new cluster at the same place)."""
        update = ctx.result.tracking
        self._stats.labels_created += len(update.created)
        self._stats.labels_merged += len(update.merged)
        self._stats.labels_removed += len(update.removed)
        for child, parents in update.merged.items():
            self._relabel(child, parents, ctx.directions[child].bearing)
        retired = [label for parents in update.merged.values() for label in parents]
        self._remember_retired((*update.removed, *retired))
        for label in update.created:
            self._reidentify(ctx.directions[label])
        if self._selected is not None and self._selected not in ctx.directions:
            successor = self._successor(ctx)
            if successor is None:
                self._stats.selected_lost += 1
                self._selected = None
            else:
                self._stats.followed_through_relabel += 1
                self._relabel(successor.label, (self._selected,), successor.bearing)
                self._selected = successor.label
        self._followed = ctx.directions.get(self._selected) if self._selected is not None else None
        self._previous = ctx.directions

    def _remember_retired(self, removed: tuple[int, ...]) -> None:
        horizon = self.step - self.config.reidentify_steps
        self._gone = {label: gone for label, gone in self._gone.items() if gone[1] >= horizon}
        self._gone.update({label: (self._previous[label], self.step) for label in removed if label in self._previous})

    def _reidentify(self, direction: Direction) -> None:
        """A fresh label at the place of a direction whose label was retired earlier (removed, or merged into
        another) is that direction again, no newly revealed one: it keeps its inspected state and view. (Without
        this, a cluster flickering between one and two directions started an inspection event at every split.) A
        branch splitting off a live direction is new: the T of a corridor reveals its exits that way."""
        tolerance = self.paper.directions.merge_tolerance
        former = tuple(
            label
            for label, (gone, _) in self._gone.items()
            if waypoints_coincide(direction.waypoints, gone.waypoints, tolerance)
        )
        if former:
            self._stats.labels_reidentified += 1
            self._relabel(direction.label, former, direction.bearing)

    def _relabel(self, label: int, parents: tuple[int, ...], bearing: float) -> None:
        if self._inspected.intersection(parents):
            self._inspected.add(label)
        self._views.inherit(label, parents, bearing)

    def _successor(self, ctx: StepContext) -> Direction | None:
        """The direction that took over the followed one's frontiers under a fresh label, if any."""
        update, followed = ctx.result.tracking, self._followed
        merged = [child for child, parents in update.merged.items() if self._selected in parents]
        if merged:
            return ctx.directions[merged[0]]
        if followed is None:
            return None
        tolerance = self.paper.directions.merge_tolerance
        fresh = [ctx.directions[label] for label in update.created]
        same = [d for d in fresh if waypoints_coincide(d.waypoints, followed.waypoints, tolerance)]
        return same[0] if same else None

    def _activity(self, action: Action) -> str:
        """What this step's action was spent on (the steps-by-activity counter)."""
        if action == Action.STOP:
            return "stop"
        if self._mode in (Mode.FOLLOW, Mode.APPROACH) and self._planner.escaping:
            return "escape"
        if self._mode is Mode.SCAN:
            return "scan" if self._stats.decisions else "start_scan"
        return str(self._mode.value)

    def decision_stats(self) -> DecisionStats:
        return self._stats.freeze(*self._search.outcome())

    def _record_views(self, observation: Observation, ctx: StepContext) -> None:
        self._views.retain([*ctx.directions, *self._gone])
        if not self.config.use_reasoner:
            return
        for label, updated in self._views.observe(ctx.result.directions, observation, self.step):
            view = self._views.get(label)
            if view is not None:
                self.trace.add(ViewCaptured(self.step, label, view.pose.yaw, view.error, updated))

    def _track_target(self) -> None:
        """Switch to approaching a target candidate when one appears; drop it when it is rejected."""
        current = self._search.current()
        if self._target is not None and (current is None or current.candidate_id != self._target):
            self._target, self._goal = None, None  # back to the followed direction (a decision if it is gone)
            self._mode = Mode.FOLLOW
            self._planner.reset()
            self.start_segment(self.step)
        if current is not None and self._target is None:
            self._target = current.candidate_id
            self._detour_steps = 0
            self._mode = Mode.APPROACH
            self._planner.reset()
            self.start_segment(self.step)

    def episode_stats(self) -> ModelStats:
        calls = self._reasoner.calls
        kinds = sorted({c.kind for c in calls})
        search = self._search
        return ModelStats(
            vlm_calls_by_kind={k: sum(c.kind == k for c in calls) for k in kinds},
            vlm_latency_ms={k: round(sum(c.latency_ms for c in calls if c.kind == k), 2) for k in kinds},
            vlm_fallbacks=sum(c.outcome == "fallback" for c in calls),
            enrich_rounds=search.enrich_rounds,
            verifications={k: search.verifications.get(k, 0) for k in ("accepted", "rejected", "uncertain")},
            phrase=search.phrase,
        )

    # ----------------------------------------------------------------- policy

    def _policy(self, observation: Observation, ctx: StepContext) -> Action:
        if self._mode is Mode.APPROACH:
            action = self._approach(observation, ctx)
            if action is not None:
                return action
        if self._mode is Mode.SCAN:
            if self._scan_turns > 0:
                self._scan_turns -= 1
                return Action.TURN_LEFT
            return self._decide(observation, ctx, "scan")
        if self._mode is Mode.SWEEP:
            action = self._continue_sweep(ctx.pose.yaw)
            return action if action is not None else self._decide(observation, ctx, "inspection")
        if self._mode is Mode.ENRICH:
            return self._enrich(observation, ctx)
        return self._follow(observation, ctx)

    def _enrich(self, observation: Observation, ctx: StepContext) -> Action:
        """Face the direction whose view shows the target, then run prompt enrichment on that frame."""
        direction = ctx.directions.get(self._enrich_label) if self._enrich_label is not None else None
        if direction is None:
            self._mode = Mode.FOLLOW
            return self._follow(observation, ctx)
        action = turn_toward(ctx.pose.yaw, direction.bearing, self._turn)
        if action is not None:
            return action
        error = abs(wrap_angle(ctx.pose.yaw - direction.bearing))
        rgb, semantic = observation.rgb, observation.semantic
        view = View(direction.label, rgb, semantic, ctx.pose, direction.bearing, error, self.step)
        self._enriched.add(direction.label)
        self._search.enrich(observation, view, self._descriptions.get(direction.label, ""), self.trace)
        self._mode = Mode.FOLLOW
        self._track_target()
        return self._policy(observation, ctx)

    def _follow(self, observation: Observation, ctx: StepContext) -> Action:
        if not self.config.use_reasoner:
            return self._follow_nearest(observation, ctx)
        if self._start_inspection(ctx):
            return self._policy(observation, ctx)
        if self._selected not in ctx.directions:
            return self._decide(observation, ctx, "vanished")
        direction = ctx.directions[self._selected]
        self._goal = direction.farthest_point
        action = self._planner.act(self._path(ctx, direction), ctx.pose, observation.collided, ctx.free)
        if action is None:
            self._blacklist[direction.label] = self.step + self.config.blacklist_steps
            return self._decide(observation, ctx, "stuck")
        return action

    def _path(self, ctx: StepContext, direction: Direction) -> NDArray[np.float64] | None:
        """The path to the goal, or to the direction's nearest reachable frontier when the goal is unreachable."""
        if ctx.goal_path is not None:
            return ctx.goal_path
        members = [ctx.result.paths[f] for f in direction.frontier_ids if f in ctx.result.paths]
        return min(members, key=lambda p: p.travel_time).path if members else None

    def _start_inspection(self, ctx: StepContext) -> bool:
        """An inspection event (Sec. IV-A c): new forward directions lack views; True if rotation starts."""
        fresh = [
            d
            for d in needs_inspection(ctx.result.directions, self._views, ctx.pose.yaw, self.paper.inspection)
            if d.label not in self._inspected
        ]
        if not fresh:
            return False
        self._inspected.update(ctx.directions)
        self._event_heading = ctx.pose.yaw
        self._stats.inspection_events += 1
        if self.config.decision_scan:
            self._mode, self._scan_turns = Mode.SCAN, full_scan_turns(self._turn)
            self.trace.add(ScanStarted(self.step, self._scan_turns))
            return True
        self._pending_yaws = plan_sweep(ctx.pose.yaw, [d.bearing for d in fresh], self._turn)
        self.trace.add(InspectionStarted(self.step, tuple(d.label for d in fresh), tuple(self._pending_yaws)))
        self._mode = Mode.SWEEP
        return True

    def _continue_sweep(self, yaw: float) -> Action | None:
        while self._pending_yaws:
            action = turn_toward(yaw, self._pending_yaws[0], self._turn)
            if action is not None:
                return action
            self._pending_yaws.pop(0)
        return None

    # ----------------------------------------------------------------- decisions

    def _candidates(self, ctx: StepContext, reason: str) -> list[Candidate]:
        """The still-relevant directions a decision offers (module docstring; docs/agent.md)."""
        usable = [d for d in ctx.result.directions if self._blacklist.get(d.label, -1) < self.step]
        if not usable:
            self._blacklist.clear()
            usable = list(ctx.result.directions)
        if self._forward_only(reason):
            heading = self._event_heading if reason == "inspection" else ctx.pose.yaw
            half_range = self.paper.inspection.forward_range / 2.0
            forward = [d for d in usable if within(signed_offset(d.bearing, heading), half_range)]
            if not forward:
                self._stats.dead_end_decisions += 1
            usable = forward or usable
        with_views = [d for d in usable if self._views.has_view(d.label)]
        return [self._candidate(ctx, d) for d in (with_views or usable)]

    def _forward_only(self, reason: str) -> bool:
        """Whether a decision is restricted to the forward 240 deg: every one after the start scan, unless the
        method scans 360 deg at each decision or is the "w/o 240 deg" ablation (Sec. IV-A c, Table V)."""
        return reason != "scan" and self.paper.inspection.restrict_forward and not self.config.decision_scan

    def _candidate(self, ctx: StepContext, direction: Direction) -> Candidate:
        times = [ctx.result.paths[f].travel_time for f in direction.frontier_ids if f in ctx.result.paths]
        return Candidate(
            label=direction.label,
            bearing=direction.bearing,
            turn=wrap_angle(direction.bearing - ctx.pose.yaw),
            travel_time=min(times) if times else math.inf,
            frontier_cells=len(direction.points),
            view=self._views.get(direction.label),
            current=direction.label == self._selected,
        )

    def _decide(self, observation: Observation, ctx: StepContext, reason: str) -> Action:
        """Ask the reasoner for the next direction, then take the first step toward it."""
        self._inspected.update(ctx.directions)
        candidates = self._candidates(ctx, reason)
        if not candidates:
            return self.stop("no_frontier")
        self._stats.decisions[reason] += 1
        selection = self._reasoner.select_direction(self.goal_text, candidates)
        self._descriptions.update(selection.descriptions)
        by_label = {c.label: c for c in candidates}
        label = self._chosen_label(selection, by_label, candidates)
        direction = ctx.directions[label]
        self._select(direction, reason, [c.label for c in candidates], selection.fallback)
        wants_enrichment = self.config.enrich and label not in self._enriched and self._search.current() is None
        if label == selection.target_label and wants_enrichment:
            self._enrich_label, self._mode = label, Mode.ENRICH
            return self._enrich(observation, ctx)
        ctx = self._replan(ctx, direction.farthest_point)
        self._mode = Mode.FOLLOW
        action = self._planner.act(self._path(ctx, direction), ctx.pose, observation.collided, ctx.free)
        return (
            action
            if action is not None
            else (turn_toward(ctx.pose.yaw, direction.bearing, self._turn) or Action.TURN_LEFT)
        )

    @staticmethod
    def _chosen_label(selection: Selection, by_label: dict[int, Candidate], candidates: list[Candidate]) -> int:
        """The direction to follow: toward the target when the reasoner sees it (Sec. IV-B), else its choice."""
        if selection.target_visible and selection.target_label in by_label:
            return int(selection.target_label)
        return selection.label if selection.label in by_label else _nearest(candidates)

    def _select(self, direction: Direction, reason: str, candidates: list[int], fallback: bool) -> None:
        """Follow ``direction``; choosing a different direction starts a new segment (revisit metric)."""
        if direction.label != self._selected:
            self._planner.reset()
            self.start_segment(self.step)
        self._selected = direction.label
        self._goal = direction.farthest_point
        self.trace.add(
            DirectionSelected(
                self.step,
                direction.label,
                direction.bearing,
                direction.farthest_point,
                tuple(candidates),
                reason,
                fallback,
            )
        )

    def _follow_nearest(self, observation: Observation, ctx: StepContext) -> Action:
        """Greedy baseline: head for the nearest frontier point (least weighted-FMM time, at least
        ``min_goal_distance`` away) and keep it until it is explored or cannot be reached. A new segment (revisit
        metric, Sec. V-C) starts when it switches to a different frontier, not when its frontier recedes."""
        self._failed_goals = [(g, until) for g, until in self._failed_goals if until >= self.step]
        paths = [
            p
            for p in ctx.result.paths.values()
            if not any(math.dist(p.target, g) < self.config.min_goal_distance for g, _ in self._failed_goals)
        ]
        if not paths:
            return self.stop("no_frontier")
        tolerance = self.paper.directions.merge_tolerance
        current = [p for p in paths if self._goal is not None and math.dist(p.target, self._goal) <= tolerance]
        if current:
            chosen = min(current, key=lambda p: math.dist(p.target, self._goal or p.target))
        else:
            far_enough = [p for p in paths if p.travel_time >= self.config.min_goal_distance]
            chosen = min(far_enough or paths, key=lambda p: p.travel_time)
            self._switch_frontier(ctx, chosen.frontier_id)
            self._planner.reset()
        self._goal = chosen.target
        action = self._planner.act(chosen.path, ctx.pose, observation.collided, ctx.free)
        if action is not None:
            return action
        self._failed_goals.append((chosen.target, self.step + self.config.blacklist_steps))
        self._goal = None
        return turn_toward(ctx.pose.yaw, chosen.bearing, self._turn) or Action.TURN_LEFT

    def _switch_frontier(self, ctx: StepContext, frontier_id: int) -> None:
        """Greedy baseline: a new goal starts a segment unless it lies on the frontier headed for so far (the
        same frontier, receded by at most one forward step beyond the merge tolerance)."""
        points = next(f.points for f in ctx.frontiers if f.frontier_id == frontier_id)
        tolerance = self.paper.directions.merge_tolerance + self.sim.forward_step
        if not waypoints_coincide(points, self._goal_frontier, tolerance):
            self.start_segment(self.step)
        self._goal_frontier = points

    # ----------------------------------------------------------------- target approach

    def _approach(self, observation: Observation, ctx: StepContext) -> Action | None:
        """Drive to the accepted target and STOP; a target that cannot be reached is rejected."""
        assert self._target is not None
        candidate = self._search.objects.get(self._target)
        here = (ctx.pose.x, ctx.pose.y)
        closest = nearest_point(candidate, here)
        distance = math.dist(here, closest)
        if distance <= self.config.stop_distance:
            if candidate.status != "accepted":
                self._search.verify_now(observation, self._target, self.trace)
                self._track_target()
                if self._target is None:
                    return None
            if self._target in self._search.seen_now:
                return self.stop("target_reached")
            bearing = math.atan2(candidate.center[1] - ctx.pose.y, candidate.center[0] - ctx.pose.x)
            return turn_toward(ctx.pose.yaw, bearing, self._turn) or self.stop("target_reached")
        if self._goal is None or math.dist(self._goal, closest) > self.config.replan_shift:
            ctx = self._replan(ctx, closest)
        self._goal = closest
        path = ctx.goal_path
        if path is None:
            path = self._detour(ctx, closest)
            self._detour_steps += 1
        action = self._planner.act(path, ctx.pose, observation.collided, ctx.free)
        if action is not None and self._detour_steps <= self.config.approach_detour_steps:
            return action
        if distance <= self.config.give_up_distance and candidate.status == "accepted":
            return self.stop("target_reached")
        self._search.set_aside(self._target, self.step + self.config.blacklist_steps, self.trace)
        self._track_target()
        return None

    @staticmethod
    def _detour(ctx: StepContext, target: Point) -> NDArray[np.float64] | None:
        """The path to the frontier nearest the target: the way toward a target seen beyond the mapped space."""
        paths = list(ctx.result.paths.values())
        return min(paths, key=lambda p: math.dist(p.target, target)).path if paths else None


@dataclass
class _Counts:
    """The episode's :class:`~drivenav.agent.base.DecisionStats`, while it runs."""

    labels_created: int = 0
    labels_merged: int = 0
    labels_removed: int = 0
    inspection_events: int = 0
    decisions: Counter[str] = field(default_factory=Counter)
    dead_end_decisions: int = 0
    followed_through_relabel: int = 0
    selected_lost: int = 0
    labels_reidentified: int = 0
    steps: Counter[str] = field(default_factory=Counter)
    turn_reversals: int = 0
    last_turn: Action | None = None

    def count_step(self, action: Action, activity: str) -> None:
        self.steps[activity] += 1
        turns = (Action.TURN_LEFT, Action.TURN_RIGHT)
        if action in turns and self.last_turn in turns and action != self.last_turn:
            self.turn_reversals += 1
        self.last_turn = action

    def freeze(self, candidates: int, accepted: int, set_aside: int) -> DecisionStats:
        return DecisionStats(
            labels_created=self.labels_created,
            labels_merged=self.labels_merged,
            labels_removed=self.labels_removed,
            inspection_events=self.inspection_events,
            decisions_by_reason=dict(sorted(self.decisions.items())),
            dead_end_decisions=self.dead_end_decisions,
            followed_through_relabel=self.followed_through_relabel,
            selected_lost=self.selected_lost,
            labels_reidentified=self.labels_reidentified,
            steps_by_activity=dict(sorted(self.steps.items())),
            turn_reversals=self.turn_reversals,
            target_candidates=candidates,
            targets_accepted=accepted,
            targets_set_aside=set_aside,
        )


def _nearest(candidates: list[Candidate]) -> int:
    return min(candidates, key=lambda c: (c.travel_time, abs(c.turn))).label


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0
