"""Following the selected direction (paper Sec. IV overview, IV-A c).

Between reasoning events the low-level planner drives toward the farthest frontier point of the selected
direction, re-planned every step, until an inspection event interrupts it, the direction is gone (a ``vanished``
decision) or the planner cannot follow it (the direction is blacklisted for a while and a ``stuck`` decision
follows). A followed direction that only got a fresh label is still followed
(:mod:`~drivenav.agent.explorers.drive_nav.relabel`). With ``return_aware`` (beyond the paper) a direction chosen
when nothing was left ahead is followed toward its nearest frontier instead
(:func:`~drivenav.agent.explorers.drive_nav.decision.goal_point`). With ``target_check`` a forward view the
reasoner has not judged and the image-text scorer rates high is judged at once
(:func:`~drivenav.agent.explorers.drive_nav.sweep.promising_views`).
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.drive_nav.decision import decide, goal_point
from drivenav.agent.explorers.drive_nav.memory import Directions
from drivenav.agent.explorers.drive_nav.sweep import inspection_event, promising_views
from drivenav.agent.handles import StepHandles
from drivenav.types import Action, Observation


def act(d: Directions, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action:
    """The next step toward the selected direction's farthest frontier point, or a decision."""
    if inspection_event(d, handles, ctx):
        return handles.policy(observation, ctx)
    promising = promising_views(d, handles, ctx)
    if promising:  # the view is there: the reasoner judges it now, without a turn
        d.checked.update(promising)
        d.event_heading = ctx.pose.yaw
        return decide(d, handles, observation, ctx, "inspection")
    if d.selected not in ctx.directions:
        return decide(d, handles, observation, ctx, "vanished")
    direction = ctx.directions[d.selected]
    state = handles.state
    state.goal = goal_point(d, ctx, direction)
    action = state.planner.act(ctx.path_along(direction), ctx.pose, observation.collided, ctx.free)
    if action is None:
        d.blacklist[direction.label] = handles.step + handles.tuning.config.blacklist_steps
        return decide(d, handles, observation, ctx, "stuck")
    return action
