"""Early abandonment of a dead end (ours, beyond the paper; ``abandon_dead_ends``, ``drive-nav-plus``).

The paper's agent follows the selected direction's farthest frontier point "until an inspection event occurs"
(Sec. IV); when the branch turns out a dead end it drives to its very end, and the way back is one long return
over its own path (docs/ablations-v2/revisits.md: 18 of drive-nav's 19 revisits on v2). The map shows a dead end
before the robot reaches its end: the walls round the room or the corridor's end come into view, and the
unexplored space the followed direction's frontier opens onto (:mod:`~drivenav.agent.explorers.directions.evidence`)
collapses. Once that space is below ``abandon_area`` while another direction in the forward 240 deg (Sec. IV-A c)
still opens onto at least as much, the direction is given up (left out of the decisions that follow, unless
nothing else is left) and the reasoner decides anew (an ``abandoned`` decision), instead of driving on to the end.
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.directions.evidence import open_areas
from drivenav.agent.explorers.directions.memory import Directions
from drivenav.agent.loop import Loop
from drivenav.directions import Direction
from drivenav.inspection.sweep import signed_offset, within


def dead_end(d: Directions, loop: Loop, ctx: StepContext, followed: Direction) -> bool:
    """Whether the followed direction is a dead end to give up now (module docstring)."""
    config, mapper = d.config, loop.state.mapper
    if open_areas(mapper, ctx, [followed], config.evidence_reach)[0] >= config.abandon_area:
        return False
    half_range = loop.tuning.paper.inspection.forward_range / 2.0
    others = [
        x
        for x in ctx.result.directions
        if x.label != followed.label
        and x.label not in d.abandoned
        and within(signed_offset(x.bearing, ctx.pose.yaw), half_range)
    ]
    return any(area >= config.abandon_area for area in open_areas(mapper, ctx, others, config.evidence_reach))
