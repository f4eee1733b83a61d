"""A reasoner decision: which direction to follow next (paper Sec. IV-A c, IV-B).

A decision comes after the start scan (``scan``), after an inspection sweep (``inspection``), when the followed
direction is gone (``vanished``) and when it cannot be followed (``stuck``). It offers the reasoner the
still-relevant directions (docs/agent.md): after the start scan every direction; afterwards only those (not
blacklisted, with a view) within the forward 240 deg of the heading at the decision -- at an inspection event,
the heading when it began -- unless none is left there (a dead end), when the rear range is offered too. The
chosen direction is followed toward its farthest frontier point; a direction whose view shows the target, which
the grounder has not found, is enriched first (Sec. IV-B).
"""

from __future__ import annotations

import math

from drivenav.agent.context import StepContext, replan
from drivenav.agent.loop import Loop
from drivenav.agent.state import Mode
from drivenav.agent.trace import DirectionSelected
from drivenav.directions import Direction
from drivenav.grid import wrap_angle
from drivenav.inspection import turn_toward
from drivenav.inspection.sweep import signed_offset, within
from drivenav.semantics.protocols import Candidate, Selection
from drivenav.types import Action, Observation


def decide(loop: Loop, observation: Observation, ctx: StepContext, reason: str) -> Action:
    """Ask the reasoner for the next direction, then take the first step toward it (or start enrichment)."""
    state = loop.state
    state.inspected.update(ctx.directions)
    offered = candidates(loop, ctx, reason)
    if not offered:
        return loop.stop("no_frontier")
    state.counts.decisions[reason] += 1
    selection = state.reasoner.select_direction(loop.host.goal_text, offered)
    state.descriptions.update(selection.descriptions)
    label = _chosen_label(selection, offered)
    direction = ctx.directions[label]
    select(loop, direction, reason, [c.label for c in offered], selection.fallback)
    wants_enrichment = loop.tuning.config.enrich and label not in state.enriched and state.search.current() is None
    if label == selection.target_label and wants_enrichment:
        state.enrich_label, state.mode = label, Mode.ENRICH
        return loop.policy(observation, ctx)
    return _first_step(loop, observation, ctx, direction)


def candidates(loop: Loop, ctx: StepContext, reason: str) -> list[Candidate]:
    """The still-relevant directions a decision offers (module docstring; docs/agent.md)."""
    state = loop.state
    usable = [d for d in ctx.result.directions if state.blacklist.get(d.label, -1) < loop.step]
    if not usable:
        state.blacklist.clear()
        usable = list(ctx.result.directions)
    if _forward_only(loop, reason):
        heading = state.event_heading if reason == "inspection" else ctx.pose.yaw
        half_range = loop.tuning.paper.inspection.forward_range / 2.0
        forward = [d for d in usable if within(signed_offset(d.bearing, heading), half_range)]
        if not forward:
            state.counts.dead_end_decisions += 1
        usable = forward or usable
    with_views = [d for d in usable if state.views.has_view(d.label)]
    return [_candidate(loop, ctx, d) for d in (with_views or usable)]


def select(loop: Loop, direction: Direction, reason: str, offered: list[int], fallback: bool) -> None:
    """Follow ``direction``; choosing a different direction starts a new segment (revisit metric, Sec. V-C)."""
    state = loop.state
    if direction.label != state.selected:
        state.planner.reset()
        loop.start_segment()
    state.selected = direction.label
    state.goal = direction.farthest_point
    event = DirectionSelected(
        loop.step, direction.label, direction.bearing, direction.farthest_point, tuple(offered), reason, fallback
    )
    loop.trace.add(event)


def _first_step(loop: Loop, observation: Observation, ctx: StepContext, direction: Direction) -> Action:
    """Re-plan toward the direction's farthest frontier point and take the first step of following it; turn
    toward its bearing when the planner has no step."""
    state = loop.state
    ctx = replan(state.pipeline, ctx, direction.farthest_point)
    state.mode = Mode.FOLLOW
    action = state.planner.act(ctx.path_along(direction), ctx.pose, observation.collided, ctx.free)
    if action is not None:
        return action
    return turn_toward(ctx.pose.yaw, direction.bearing, loop.tuning.turn) or Action.TURN_LEFT


def _forward_only(loop: Loop, reason: str) -> bool:
    """Whether a decision is restricted to the forward 240 deg: every one after the start scan, unless the
    method scans 360 deg at each decision or is the "w/o 240 deg" ablation (Sec. IV-A c, Table V)."""
    inspection = loop.tuning.paper.inspection
    return reason != "scan" and inspection.restrict_forward and not loop.tuning.config.decision_scan


def _candidate(loop: Loop, ctx: StepContext, direction: Direction) -> Candidate:
    """What the reasoner is told of a direction: bearing, turn from the heading, travel time, view."""
    times = [ctx.result.paths[f].travel_time for f in direction.frontier_ids if f in ctx.result.paths]
    return Candidate(
        label=direction.label,
        bearing=direction.bearing,
        turn=wrap_angle(direction.bearing - ctx.pose.yaw),
        travel_time=min(times) if times else math.inf,
        frontier_cells=len(direction.points),
        view=loop.state.views.get(direction.label),
        current=direction.label == loop.state.selected,
    )


def _chosen_label(selection: Selection, offered: list[Candidate]) -> int:
    """The direction to follow: toward the target when the reasoner sees it (Sec. IV-B), else its choice, else
    the nearest one."""
    labels = {c.label for c in offered}
    if selection.target_visible and selection.target_label in labels:
        return int(selection.target_label)
    if selection.label in labels:
        return selection.label
    return min(offered, key=lambda c: (c.travel_time, abs(c.turn))).label
