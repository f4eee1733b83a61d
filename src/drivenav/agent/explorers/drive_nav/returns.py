"""Where a turn back drives (ours, beyond the paper; ``return_aware``, ``drive-nav-plus``, docs/agent.md "Beyond the
paper").

The paper's agent follows the selected direction's farthest frontier point (Sec. IV-A c). When the direction turns
out a dead end the options left lie behind the robot, and a direction seen from the end of a branch gathers every
frontier behind it within 45 deg: its nearest frontier is typically 1-3 m away, its farthest point 10-20 m back
over the path already driven. Driving to the farthest point passes the near remainder by, and a later return
comes back for it (docs/ablations-v2/revisits.md). :func:`nearest_target` is where a direction chosen with nothing
left ahead is followed instead (:func:`~drivenav.agent.explorers.drive_nav.decision.goal_point`).
"""

from __future__ import annotations

from drivenav.agent.context import StepContext
from drivenav.directions import Direction


def nearest_target(ctx: StepContext, direction: Direction) -> tuple[float, float] | None:
    """The reachable cell of the direction's member frontier nearest in travel time (None when none is reachable)."""
    members = [ctx.result.paths[f] for f in direction.frontier_ids if f in ctx.result.paths]
    return min(members, key=lambda p: p.travel_time).target if members else None
