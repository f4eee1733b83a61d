"""Prompt enrichment (paper Sec. IV-B): the reasoner reported the target in a direction's view but the grounder
has no candidate yet. The robot turns to face that direction, then the reasoner proposes detector phrases that
the grounder tests on this frame (:meth:`~drivenav.agent.target.TargetSearch.enrich`); a phrase that grounds
starts the approach, otherwise the direction is followed. Each direction is enriched at most once."""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.loop import Loop
from drivenav.agent.modes.approach import track_target
from drivenav.agent.state import Mode
from drivenav.grid import wrap_angle
from drivenav.inspection import turn_toward
from drivenav.semantics.protocols import View
from drivenav.types import Action, Observation


def act(loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """Face the direction whose view shows the target, then run prompt enrichment on that frame."""
    state = loop.state
    direction = ctx.directions.get(state.enrich_label) if state.enrich_label is not None else None
    if direction is None:  # the direction is gone: follow
        state.mode = Mode.FOLLOW
        return loop.policy(observation, ctx)
    action = turn_toward(ctx.pose.yaw, direction.bearing, loop.tuning.turn)
    if action is not None:
        return action
    error = abs(wrap_angle(ctx.pose.yaw - direction.bearing))
    view = View(direction.label, observation.rgb, observation.semantic, ctx.pose, direction.bearing, error, loop.step)
    state.enriched.add(direction.label)
    state.search.enrich(observation, view, state.descriptions.get(direction.label, ""), loop.trace)
    state.mode = Mode.FOLLOW
    track_target(loop)
    return loop.policy(observation, ctx)
