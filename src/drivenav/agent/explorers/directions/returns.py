"""The way back from a direction (ours, beyond the paper; ``return_aware``, ``drive-nav-plus``, docs/agent.md "Beyond
the paper").

The paper's agent follows the selected direction's farthest frontier point (Sec. IV-A c). When the direction turns
out a dead end, everything it passed by is left behind, and the way back is one long return over its own path
(docs/ablations-v2/revisits.md). Two measures of a direction serve the return-aware choice:

- :func:`return_time`: the travel to its farthest frontier point, where following it leads -- the weighted-FMM
  time to its member frontier farthest in travel time plus the straight line on to the point -- i.e. the way back
  from there to here should the branch end there. The reasoner is told it with each candidate;
- :func:`nearest_target`: the reachable cell of its member frontier nearest in travel time, where a direction
  chosen with nothing left ahead is followed first (:func:`~drivenav.agent.explorers.directions.decision.goal_point`).
"""

from __future__ import annotations

import math

import numpy as np

from drivenav.agent.context import StepContext
from drivenav.directions import Direction


def nearest_target(ctx: StepContext, direction: Direction) -> tuple[float, float] | None:
    """The reachable cell of the direction's member frontier nearest in travel time (None when none is reachable)."""
    members = [ctx.result.paths[f] for f in direction.frontier_ids if f in ctx.result.paths]
    return min(members, key=lambda p: p.travel_time).target if members else None


def return_time(ctx: StepContext, direction: Direction) -> float:
    """The travel to the direction's farthest frontier point (module docstring); infinite when unreachable."""
    members = [ctx.result.paths[f] for f in direction.frontier_ids if f in ctx.result.paths]
    if not members:
        return math.inf
    member = max(members, key=lambda p: p.travel_time)
    far = np.asarray(direction.farthest_point) - np.asarray(member.target)
    return member.travel_time + float(np.hypot(far[0], far[1]))
