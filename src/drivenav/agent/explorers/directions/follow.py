"""Following the selected direction (paper Sec. IV overview, IV-A c).

Between reasoning events the low-level planner drives toward the farthest frontier point of the selected
direction, re-planned every step, until an inspection event interrupts it, the direction is gone (a ``vanished``
decision) or the planner cannot follow it (the direction is blacklisted for a while and a ``stuck`` decision
follows). A followed direction that only got a fresh label is still followed
(:mod:`~drivenav.agent.explorers.directions.relabel`). With ``abandon_dead_ends`` (beyond the paper) a followed
direction that turns out a dead end is given up before its end (an ``abandoned`` decision,
:mod:`~drivenav.agent.explorers.directions.abandon`).
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.directions.abandon import dead_end
from drivenav.agent.explorers.directions.decision import decide, goal_point
from drivenav.agent.explorers.directions.memory import Directions
from drivenav.agent.explorers.directions.sweep import inspection_event
from drivenav.agent.loop import Loop
from drivenav.types import Action, Observation


def act(d: Directions, loop: Loop, observation: Observation, ctx: StepContext) -> Action:
    """The next step toward the selected direction's farthest frontier point, or a decision."""
    if inspection_event(d, loop, ctx):
        return loop.policy(observation, ctx)
    if d.selected not in ctx.directions:
        return decide(d, loop, observation, ctx, "vanished")
    direction = ctx.directions[d.selected]
    if d.config.abandon_dead_ends and dead_end(d, loop, ctx, direction):
        d.abandoned.add(direction.label)
        return decide(d, loop, observation, ctx, "abandoned")
    state = loop.state
    state.goal = goal_point(d, ctx, direction)
    action = state.planner.act(ctx.path_along(direction), ctx.pose, observation.collided, ctx.free)
    if action is None:
        d.blacklist[direction.label] = loop.step + loop.tuning.config.blacklist_steps
        return decide(d, loop, observation, ctx, "stuck")
    return action
