"""Following the selected direction (paper Sec. IV overview, IV-A c).

Between reasoning events the low-level planner drives toward the farthest frontier point of the selected
direction, re-planned every step, until an inspection event interrupts it, the direction is gone (a ``vanished``
decision) or the planner cannot follow it (the direction is blacklisted for a while and a ``stuck`` decision
follows). A followed direction that only got a fresh label is still followed (:mod:`drivenav.agent.relabel`).
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.decision import decide
from drivenav.agent.loop import Loop
from drivenav.agent.modes.sweep import inspection_event
from drivenav.types import Action, Observation


def act(loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """The next step toward the selected direction's farthest frontier point, or a decision."""
    if inspection_event(loop, ctx):
        return loop.policy(observation, ctx)
    state = loop.state
    if state.selected not in ctx.directions:
        return decide(loop, observation, ctx, "vanished")
    direction = ctx.directions[state.selected]
    state.goal = direction.farthest_point
    action = state.planner.act(ctx.path_along(direction), ctx.pose, observation.collided, ctx.free)
    if action is None:
        state.blacklist[direction.label] = loop.step + loop.tuning.config.blacklist_steps
        return decide(loop, observation, ctx, "stuck")
    return action
