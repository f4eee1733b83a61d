"""The inspection sweep (paper Sec. IV-A c, Fig. 3).

While a direction is followed, an *inspection event* occurs when the evolving frontier layout exposes directions
within the forward 240 deg that lack representative views and no event has covered yet. The agent then rotates
only over those directions, from the side needing the smaller initial turn (:func:`~drivenav.inspection.plan_sweep`;
views are recorded on the way), and the reasoner selects the next direction. With ``decision_scan`` the event
starts a full 360 deg scan instead.

With ``skip_void_events`` (ours, beyond the paper; ``drive-nav-plus``) an event whose directions are all gone when
the sweep ends -- a piece of the followed direction's frontier that split off for a few steps and merged back, or
was seen empty during the turn -- asks the reasoner nothing: it would be offered what it chose from before
(docs/ablations-v2/decisions.md). Following the selected direction goes on, if it is still tracked.
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.drive_nav.decision import decide
from drivenav.agent.explorers.drive_nav.memory import Directions, Phase, settled, unjudged
from drivenav.agent.explorers.drive_nav.scan import start as start_scan
from drivenav.agent.handles import StepHandles
from drivenav.agent.trace import InspectionStarted, InspectionVoid
from drivenav.directions import Direction
from drivenav.inspection import needs_inspection, plan_sweep, turn_toward
from drivenav.inspection.views import forward_of, inspectable
from drivenav.types import Action, Observation


def act(d: Directions, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
    """Turn toward the next yaw of the sweep; once every yaw is faced, decide (or, for a void event, follow on)."""
    action = _continue_sweep(d, handles, ctx.pose.yaw)
    if action is not None:
        return action
    if d.config.skip_void_events and void(d, handles, ctx):
        d.counts.void_events += 1
        handles.trace.add(InspectionVoid(handles.step, d.event_labels))
        d.enter(handles, Phase.FOLLOW)
        return handles.policy(observation, ctx)
    return decide(d, handles, observation, ctx, "inspection")


def void(d: Directions, handles: StepHandles, ctx: StepContext) -> bool:
    """Whether the event just swept is void: none of the directions that started it is tracked any more, the
    direction followed before it still is, and the sweep left the reasoner nothing new to judge -- every forward
    direction's view is one it has seen (a view captured during the sweep may show the target)."""
    if d.selected not in ctx.directions or any(label in ctx.directions for label in d.event_labels):
        return False
    forward = forward_of(ctx.result.directions, d.event_heading, handles.tuning.paper.inspection.forward_range)
    return not any(unjudged(d, d.views.get(x.label)) for x in forward)


def inspection_event(d: Directions, handles: StepHandles, ctx: StepContext) -> bool:
    """Start an inspection event if new forward directions lack views (with ``settle_steps``: new settled forward
    directions the reasoner has not judged); True if it starts."""
    fresh = [
        direction
        for direction in _due(d, handles, ctx)
        if direction.label not in d.inspected and settled(d, handles.step, direction.label)
    ]
    if not fresh:
        return False
    d.inspected.update(label for label in ctx.directions if settled(d, handles.step, label))
    d.event_heading = ctx.pose.yaw
    d.event_labels = tuple(direction.label for direction in fresh)
    d.counts.inspection_events += 1
    if d.config.decision_scan:
        start_scan(d, handles)
        return True
    unseen = [direction.bearing for direction in fresh if not d.views.has_view(direction.label)]
    d.pending_yaws = plan_sweep(ctx.pose.yaw, unseen, handles.tuning.turn)
    handles.trace.add(InspectionStarted(handles.step, tuple(x.label for x in fresh), tuple(d.pending_yaws)))
    d.enter(handles, Phase.SWEEP)
    return True


def _due(d: Directions, handles: StepHandles, ctx: StepContext) -> list[Direction]:
    """The forward directions that call for an event (Sec. IV-A c): those lacking a view. A direction that must first
    settle (``settle_steps``, beyond the paper) may have been seen in passing while it settled: it is still due while
    the reasoner has not judged its view -- a new exit is never passed by unasked."""
    settling = d.config.settle_steps > 0
    return needs_inspection(
        ctx.result.directions,
        d.views,
        ctx.pose.yaw,
        handles.tuning.paper.inspection,
        lambda x: settling and unjudged(d, d.views.get(x.label)),
    )


def promising_views(d: Directions, handles: StepHandles, ctx: StepContext) -> list[int]:
    """With ``target_check`` (ours, beyond the paper): whether a forward direction has a view the reasoner has not
    judged whose frame the image-text scorer rated at least ``target_check``. Such a view may show the target, and
    the reasoner's answer whether it does is what steers the robot to it and starts prompt enrichment (Sec. IV-B);
    with fewer decisions it would wait for the next one (docs/ablations-v2/drive-nav-plus-dev.md, C4). Each
    direction is checked so once (``checked``): a view retaken as the robot nears the target starts no more."""
    threshold = d.config.target_check
    if threshold <= 0.0:
        return []
    ahead = inspectable(ctx.result.directions, ctx.pose.yaw, handles.tuning.paper.inspection)
    views = [(x.label, d.views.get(x.label)) for x in ahead if x.label not in d.checked]
    return [
        label for label, v in views if v is not None and unjudged(d, v) and d.view_scores.get(v.step, 0.0) >= threshold
    ]


def _continue_sweep(d: Directions, handles: StepHandles, yaw: float) -> Action | None:
    """The turn toward the first yaw not yet faced, or None when the sweep is done."""
    pending = d.pending_yaws
    while pending:
        action = turn_toward(yaw, pending[0], handles.tuning.turn)
        if action is not None:
            return action
        pending.pop(0)
    return None
