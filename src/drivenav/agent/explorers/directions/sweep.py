"""The inspection sweep (paper Sec. IV-A c, Fig. 3).

While a direction is followed, an *inspection event* occurs when the evolving frontier layout exposes directions
within the forward 240 deg that lack representative views and no event has covered yet. The agent then rotates
only over those directions, from the side needing the smaller initial turn (:func:`~drivenav.inspection.plan_sweep`;
views are recorded on the way), and the reasoner selects the next direction. With ``decision_scan`` the event
starts a full 360 deg scan instead.
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.directions.decision import decide
from drivenav.agent.explorers.directions.memory import Directions, Phase
from drivenav.agent.explorers.directions.scan import start as start_scan
from drivenav.agent.loop import Loop
from drivenav.agent.trace import InspectionStarted
from drivenav.inspection import needs_inspection, plan_sweep, turn_toward
from drivenav.types import Action, Observation


def act(d: Directions, loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """Turn toward the next yaw of the sweep; once every yaw is faced, decide."""
    action = _continue_sweep(d, loop, ctx.pose.yaw)
    return action if action is not None else decide(d, loop, observation, ctx, "inspection")


def inspection_event(d: Directions, loop: Loop, ctx: StepContext) -> bool:
    """Start an inspection event if new forward directions lack views; True if rotation starts."""
    fresh = [
        direction
        for direction in needs_inspection(ctx.result.directions, d.views, ctx.pose.yaw, loop.tuning.paper.inspection)
        if direction.label not in d.inspected
    ]
    if not fresh:
        return False
    d.inspected.update(ctx.directions)
    d.event_heading = ctx.pose.yaw
    d.counts.inspection_events += 1
    if d.config.decision_scan:
        start_scan(d, loop)
        return True
    d.pending_yaws = plan_sweep(ctx.pose.yaw, [direction.bearing for direction in fresh], loop.tuning.turn)
    loop.trace.add(InspectionStarted(loop.step, tuple(x.label for x in fresh), tuple(d.pending_yaws)))
    d.enter(loop, Phase.SWEEP)
    return True


def _continue_sweep(d: Directions, loop: Loop, yaw: float) -> Action | None:
    """The turn toward the first yaw not yet faced, or None when the sweep is done."""
    pending = d.pending_yaws
    while pending:
        action = turn_toward(yaw, pending[0], loop.tuning.turn)
        if action is not None:
            return action
        pending.pop(0)
    return None
