"""A reasoner decision: which direction to follow next (paper Sec. IV-A c, IV-B).

A decision comes after the start scan (``scan``), after an inspection sweep (``inspection``), when the followed
direction is gone (``vanished``) and when it cannot be followed (``stuck``). It offers the reasoner the
still-relevant directions (docs/agent.md): after the start scan every direction; afterwards only those (not
blacklisted, with a view) within the forward 240 deg of the heading at the decision -- at an inspection event,
the heading when it began -- unless none is left there (a dead end), when the rear range is offered too. The
chosen direction is followed toward its farthest frontier point; a direction whose view shows the target, which
the grounder has not found, is enriched first (Sec. IV-B). With ``skip_void_events`` (beyond the paper) a choice
left with one direction whose view the reasoner has already judged is no question: that direction is followed
(``forced_choices``), and the reasoner is asked only where it has something new to judge.
"""

from __future__ import annotations

import math

from drivenav.agent.context import StepContext, replan
from drivenav.agent.explorers.drive_nav.memory import Directions, Phase, settled, unjudged
from drivenav.agent.explorers.drive_nav.returns import nearest_target
from drivenav.agent.handles import StepHandles
from drivenav.agent.trace import DirectionSelected
from drivenav.directions import Direction
from drivenav.grid import wrap_angle
from drivenav.inspection import turn_toward
from drivenav.inspection.views import forward_of
from drivenav.semantics.protocols import Candidate, Selection
from drivenav.types import Action, Observation, Pose


def decide(d: Directions, handles: StepHandles, observation: Observation, ctx: StepContext, reason: str) -> Action:
    """Ask the reasoner for the next direction, then take the first step toward it (or start enrichment)."""
    state = handles.state
    d.inspected.update(label for label in ctx.directions if settled(d, handles.step, label))
    offered = candidates(d, handles, ctx, reason)
    if not offered:
        return handles.stop("no_frontier")
    if forced(d, offered):
        d.counts.forced_choices += 1
        direction = ctx.directions[offered[0].label]
        select(d, handles, ctx, direction, reason, [direction.label], False)
        return _first_step(d, handles, observation, ctx, direction)
    d.counts.decisions[reason] = d.counts.decisions.get(reason, 0) + 1
    selection = state.reasoner.select_direction(handles.host.goal_text, offered)
    d.judged.update(c.view.step for c in offered if c.view is not None)
    d.descriptions.update(selection.descriptions)
    label = _chosen_label(selection, offered)
    direction = ctx.directions[label]
    select(d, handles, ctx, direction, reason, [c.label for c in offered], selection.fallback)
    wants_enrichment = handles.tuning.config.enrich and label not in d.enriched and state.search.current() is None
    if label == selection.target_label and wants_enrichment:
        d.enrich_label = label
        d.enter(handles, Phase.ENRICH)
        return handles.policy(observation, ctx)
    return _first_step(d, handles, observation, ctx, direction)


def forced(d: Directions, offered: list[Candidate]) -> bool:
    """Whether the choice is forced, with nothing for the reasoner to judge (``skip_void_events``, beyond the paper):
    a single direction is offered and the reasoner has already seen its view (or it has none)."""
    if not d.config.skip_void_events or len(offered) != 1:
        return False
    return not unjudged(d, offered[0].view)


def candidates(d: Directions, handles: StepHandles, ctx: StepContext, reason: str) -> list[Candidate]:
    """The still-relevant directions a decision offers (module docstring; docs/agent.md)."""
    usable = [x for x in ctx.result.directions if d.blacklist.get(x.label, -1) < handles.step]
    if not usable:
        d.blacklist.clear()
        usable = list(ctx.result.directions)
    d.turning_back = False
    if _forward_only(d, handles, reason):
        heading = d.event_heading if reason == "inspection" else ctx.pose.yaw
        forward = forward_of(usable, heading, handles.tuning.paper.inspection.forward_range)
        if not forward:
            d.counts.dead_end_decisions += 1
        d.turning_back = not forward
        usable = forward or usable
    with_views = [x for x in usable if d.views.has_view(x.label)]
    return [_candidate(d, ctx, x) for x in (with_views or usable)]


def select(
    d: Directions,
    handles: StepHandles,
    ctx: StepContext,
    direction: Direction,
    reason: str,
    offered: list[int],
    fallback: bool,
) -> None:
    """Follow ``direction``; choosing a different direction starts a new segment (revisit metric, Sec. V-C)."""
    if direction.label != d.selected:
        handles.state.planner.reset()
        handles.start_segment()
    d.selected = direction.label
    d.returning = d.config.return_aware and d.turning_back
    goal = goal_point(d, ctx, direction)
    handles.state.goal = goal
    event = DirectionSelected(handles.step, direction.label, direction.bearing, goal, tuple(offered), reason, fallback)
    handles.trace.add(event)


def goal_point(d: Directions, ctx: StepContext, direction: Direction) -> tuple[float, float]:
    """Where following ``direction`` drives: its farthest frontier point (Sec. IV-A c) or, turning back with
    ``return_aware`` (beyond the paper), its nearest frontier -- the remainder near the dead end is finished before
    the long way back, which would pass it by and come back for it."""
    if d.returning:
        near = nearest_target(ctx, direction)
        if near is not None:
            return near
    return direction.farthest_point


def _first_step(
    d: Directions, handles: StepHandles, observation: Observation, ctx: StepContext, direction: Direction
) -> Action:
    """Re-plan toward the direction's goal point (:func:`goal_point`) and take the first step of following it; turn
    toward its bearing when the planner has no step."""
    state = handles.state
    ctx = replan(state.pipeline, ctx, goal_point(d, ctx, direction))
    d.enter(handles, Phase.FOLLOW)
    action = state.planner.act(ctx.path_along(direction), ctx.pose, observation.collided, ctx.free)
    if action is not None:
        return action
    return turn_toward(ctx.pose.yaw, direction.bearing, handles.tuning.turn) or Action.TURN_LEFT


def _forward_only(d: Directions, handles: StepHandles, reason: str) -> bool:
    """Whether a decision is restricted to the forward 240 deg: every one after the start scan, unless the
    method scans 360 deg at each decision or is the "w/o 240 deg" ablation (Sec. IV-A c, Table V)."""
    inspection = handles.tuning.paper.inspection
    return reason != "scan" and inspection.restrict_forward and not d.config.decision_scan


def _candidate(d: Directions, ctx: StepContext, direction: Direction) -> Candidate:
    """What the reasoner is told of a direction: bearing, turn from the heading, travel time, view."""
    times = [ctx.result.paths[f].travel_time for f in direction.frontier_ids if f in ctx.result.paths]
    return Candidate(
        label=direction.label,
        bearing=direction.bearing,
        turn=wrap_angle(direction.bearing - ctx.pose.yaw),
        travel_time=min(times) if times else math.inf,
        frontier_cells=len(direction.points),
        view=d.views.get(direction.label),
        current=direction.label == d.selected,
        frontiers=_frontier_poses(direction, ctx.pose.z),
    )


def _frontier_poses(direction: Direction, height: float) -> tuple[Pose, ...]:
    """A direction's frontier waypoints and farthest point as poses at the robot's height (:class:`Candidate`)."""
    points = [*((float(x), float(y)) for x, y in direction.waypoints), direction.farthest_point]
    return tuple(Pose(x, y, 0.0, height) for x, y in points)


def _chosen_label(selection: Selection, offered: list[Candidate]) -> int:
    """The direction to follow: toward the target when the reasoner sees it (Sec. IV-B), else its choice, else
    the nearest one."""
    labels = {c.label for c in offered}
    if selection.target_visible and selection.target_label in labels:
        return int(selection.target_label)
    if selection.label in labels:
        return selection.label
    return min(offered, key=lambda c: (c.travel_time, abs(c.turn))).label
