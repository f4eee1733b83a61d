"""The target approach (paper Sec. IV-B, IV-C): drive to the target candidate, verifying it on the way, and STOP
within ``stop_distance`` once it is accepted and in view.

While no mapped free cell leads to the target yet, the robot drives through the frontier nearest to it (a target
seen beyond the mapped space); a target it cannot get to is set aside for a while, never rejected (only
verification rejects). :func:`track_target` switches the loop into and out of this mode as candidates appear,
are accepted or go. The approach is the body's: every exploration method shares it.
"""

from __future__ import annotations

import math

from drivenav.agent.context import Point, Polyline, StepContext, replan
from drivenav.agent.handles import StepHandles
from drivenav.inspection import turn_toward
from drivenav.mapping.objects import ObjectCandidate, nearest_point
from drivenav.types import Action, Observation


def act(handles: StepHandles, observation: Observation, ctx: StepContext) -> Action | None:
    """The next step of the approach, or None when the target was dropped or set aside (the step goes on in the
    mode the loop is in now)."""
    assert handles.state.target is not None
    candidate = handles.state.search.objects.get(handles.state.target)
    here = (ctx.pose.x, ctx.pose.y)
    closest = nearest_point(candidate, here)
    distance = math.dist(here, closest)
    if distance <= handles.tuning.config.stop_distance:
        return _at_target(handles, observation, ctx, candidate)
    return _drive(handles, observation, ctx, candidate, closest, distance)


def track_target(handles: StepHandles) -> None:
    """Switch to approaching a target candidate when one appears; drop it when it is rejected or set aside."""
    state = handles.state
    current = state.search.current()
    if state.target is not None and (current is None or current.candidate_id != state.target):
        state.target, state.goal = None, None  # back to exploring, from where the explorer left off
        state.approaching = False
        handles.explorer.resume(handles)
        state.planner.reset()
        handles.start_segment()
    if current is not None and state.target is None:
        state.target = current.candidate_id
        state.detour_steps = 0
        state.approaching = True
        state.planner.reset()
        handles.start_segment()


def _at_target(
    handles: StepHandles, observation: Observation, ctx: StepContext, candidate: ObjectCandidate
) -> Action | None:
    """Within stop distance: a pending candidate gets its last verification frame (Sec. IV-C); STOP once the
    target is in the current frame, turning toward it until then (at once with ``agent.stop_in_view`` off, as
    ApexNav stops at its approach goal, seen or not)."""
    state = handles.state
    if candidate.status != "accepted":
        assert state.target is not None
        state.search.verify_now(observation, state.target, handles.trace)
        track_target(handles)
        if state.target is None:
            return None
    if state.target in state.search.seen_now or not handles.tuning.config.stop_in_view:
        return handles.stop("target_reached")
    bearing = math.atan2(candidate.center[1] - ctx.pose.y, candidate.center[0] - ctx.pose.x)
    return turn_toward(ctx.pose.yaw, bearing, handles.tuning.turn) or handles.stop("target_reached")


def _drive(
    handles: StepHandles,
    observation: Observation,
    ctx: StepContext,
    candidate: ObjectCandidate,
    closest: Point,
    distance: float,
) -> Action | None:
    """A step toward the target's nearest observed point (re-planned when it moved), through the frontier
    nearest to it while the map has no way there; STOP if stuck close to an accepted target, else set it aside."""
    state, config = handles.state, handles.tuning.config
    if state.goal is None or math.dist(state.goal, closest) > config.replan_shift:
        ctx = replan(state.pipeline, ctx, closest)
    state.goal = closest
    path = ctx.goal_path
    if path is None:
        path = _detour(ctx, closest)
        state.detour_steps += 1
    action = state.planner.act(path, ctx.pose, observation.collided, ctx.free)
    if action is not None and state.detour_steps <= config.approach_detour_steps:
        return action
    if distance <= config.give_up_distance and candidate.status == "accepted":
        return handles.stop("target_reached")
    assert state.target is not None
    state.search.set_aside(state.target, handles.step + config.blacklist_steps, handles.trace)
    track_target(handles)
    return None


def _detour(ctx: StepContext, target: Point) -> Polyline | None:
    """The path to the frontier nearest the target: the way toward a target seen beyond the mapped space."""
    paths = list(ctx.result.paths.values())
    return min(paths, key=lambda p: math.dist(p.target, target)).path if paths else None
