"""Prompt enrichment (paper Sec. IV-B): the reasoner reported the target in a direction's view but the grounder
has no candidate yet. The robot turns to face that direction, then the reasoner proposes detector phrases that
the grounder tests on this frame (:meth:`~drivenav.agent.target.TargetSearch.enrich`); a phrase that grounds
starts the approach, otherwise the direction is followed. Each direction is enriched at most once."""

from __future__ import annotations

from drivenav.agent.approach import track_target
from drivenav.agent.context import StepContext
from drivenav.agent.explorers.drive_nav.memory import Directions, Phase
from drivenav.agent.handles import StepHandles
from drivenav.grid import wrap_angle
from drivenav.inspection import turn_toward
from drivenav.semantics.protocols import View
from drivenav.types import Action, Observation


def act(d: Directions, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
    """Face the direction whose view shows the target, then run prompt enrichment on that frame."""
    direction = ctx.directions.get(d.enrich_label) if d.enrich_label is not None else None
    if direction is None:  # the direction is gone: follow
        d.enter(handles, Phase.FOLLOW)
        return handles.policy(observation, ctx)
    action = turn_toward(ctx.pose.yaw, direction.bearing, handles.tuning.turn)
    if action is not None:
        return action
    error = abs(wrap_angle(ctx.pose.yaw - direction.bearing))
    view = View(
        direction.label, observation.rgb, observation.semantic, ctx.pose, direction.bearing, error, handles.step
    )
    d.enriched.add(direction.label)
    handles.state.search.enrich(observation, view, d.descriptions.get(direction.label, ""), handles.trace)
    d.enter(handles, Phase.FOLLOW)
    track_target(handles)
    return handles.policy(observation, ctx)
