"""Following the selected direction (paper Sec. IV overview, IV-A c).

Between reasoning events the low-level planner drives toward the farthest frontier point of the selected
direction, re-planned every step, until an inspection event interrupts it, the direction is gone (a ``vanished``
decision) or the planner cannot follow it (the direction is blacklisted for a while and a ``stuck`` decision
follows). A followed direction that only got a fresh label is still followed
(:mod:`~drivenav.agent.explorers.directions.relabel`). With ``return_aware`` (beyond the paper) a direction chosen
when nothing was left ahead is followed toward its nearest frontier instead
(:func:`~drivenav.agent.explorers.directions.decision.goal_point`). With ``target_check`` a forward view the
reasoner has not judged and the image-text scorer rates high is judged at once
(:func:`~drivenav.agent.explorers.directions.sweep.promising_views`).
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.directions.decision import decide, goal_point
from drivenav.agent.explorers.directions.memory import Directions
from drivenav.agent.explorers.directions.sweep import inspection_event, promising_views
from drivenav.agent.loop import Loop
from drivenav.types import Action, Observation


def act(d: Directions, loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """The next step toward the selected direction's farthest frontier point, or a decision."""
    if inspection_event(d, loop, ctx):
        return loop.policy(observation, ctx)
    promising = promising_views(d, loop, ctx)
    if promising:  # the view is there: the reasoner judges it now, without a turn
        d.checked.update(promising)
        d.event_heading = ctx.pose.yaw
        return decide(d, loop, observation, ctx, "inspection")
    if d.selected not in ctx.directions:
        return decide(d, loop, observation, ctx, "vanished")
    direction = ctx.directions[d.selected]
    state = loop.state
    state.goal = goal_point(d, ctx, direction)
    action = state.planner.act(ctx.path_along(direction), ctx.pose, observation.collided, ctx.free)
    if action is None:
        d.blacklist[direction.label] = loop.step + loop.tuning.config.blacklist_steps
        return decide(d, loop, observation, ctx, "stuck")
    return action
