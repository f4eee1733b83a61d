"""Dead-end evidence per direction (ours, beyond the paper; ``drive-nav-plus``, docs/agent.md "Beyond the paper").

The paper's reasoner judges a direction from its representative view (Sec. IV-A c); a view rarely shows that a
branch ends a few metres on. The map does: a direction's frontier opens onto unexplored space, and once the walls
round a room or the end of a corridor have been seen that space is small. Measured per direction:

- ``open_area``: the unexplored space (m^2) where a robot could stand, reachable through the direction's frontier
  cells within ``evidence_reach`` metres of them (:meth:`~drivenav.mapping.occupancy.OccupancyMapper.open_areas`);
  a dead end has little, a branch that goes on fills the window;
- ``visited``: the share of the way to it that runs over the path driven before the current segment began
  (within ``visited_radius``; the paper's revisit radius, 0.5 m, by default) -- following a direction back
  through a region already driven through re-drives that path (the revisit of Sec. V-C); the way is the
  weighted-FMM path to its member frontier farthest in travel time (where following it leads);
- ``return_time``: the travel to its farthest frontier point (where following it leads, Sec. IV-A c) -- the
  weighted-FMM time to that member frontier plus the straight line on to the point -- i.e. the way back from
  there to here should the branch turn out a dead end (``return_aware``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from drivenav.agent.context import StepContext
from drivenav.agent.explorers.directions.config import DirectionsConfig
from drivenav.agent.explorers.directions.memory import Directions
from drivenav.agent.loop import Loop
from drivenav.directions import Direction
from drivenav.directions.types import FrontierPath
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.metrics import densify


@dataclass(frozen=True)
class Evidence:
    """What the map says of one direction (module docstring)."""

    open_area: float
    visited: float
    return_time: float


def frontier_cells(ctx: StepContext, direction: Direction) -> NDArray[np.int64]:
    """The grid cells of the direction's member frontiers."""
    by_id = {frontier.frontier_id: frontier for frontier in ctx.frontiers}
    groups = [by_id[f].cells for f in direction.frontier_ids if f in by_id]
    return np.concatenate(groups) if groups else np.zeros((0, 2), dtype=np.int64)


def open_areas(mapper: OccupancyMapper, ctx: StepContext, directions: list[Direction], reach: float) -> list[float]:
    """Each direction's ``open_area`` (module docstring)."""
    return mapper.open_areas([frontier_cells(ctx, direction) for direction in directions], reach)


def retraced_share(path: NDArray[np.float64], driven: NDArray[np.float64], radius: float) -> float:
    """The share of the polyline ``path``'s length whose segment midpoints lie within ``radius`` of a position in
    ``driven`` (0 for a path of no length or without ``driven``)."""
    if len(path) < 2 or len(driven) == 0:
        return 0.0
    lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
    total = float(lengths.sum())
    if total <= 0.0:
        return 0.0
    midpoints = 0.5 * (path[1:] + path[:-1])
    near, _ = cKDTree(densify(driven, radius / 4.0)).query(midpoints, distance_upper_bound=radius)
    return float(lengths[np.isfinite(near)].sum()) / total


def _farthest_member(ctx: StepContext, direction: Direction) -> FrontierPath | None:
    """The path of the direction's member frontier farthest in travel time (None when none is reachable)."""
    members = [ctx.result.paths[f] for f in direction.frontier_ids if f in ctx.result.paths]
    return max(members, key=lambda p: p.travel_time, default=None)


def nearest_target(ctx: StepContext, direction: Direction) -> tuple[float, float] | None:
    """The reachable cell of the direction's member frontier nearest in travel time (None when none is reachable)."""
    members = [ctx.result.paths[f] for f in direction.frontier_ids if f in ctx.result.paths]
    return min(members, key=lambda p: p.travel_time).target if members else None


def return_time(ctx: StepContext, direction: Direction) -> float:
    """The travel to the direction's farthest frontier point (module docstring); infinite when unreachable."""
    member = _farthest_member(ctx, direction)
    if member is None:
        return math.inf
    far = np.asarray(direction.farthest_point) - np.asarray(member.target)
    return member.travel_time + float(np.hypot(far[0], far[1]))


def visited(ctx: StepContext, direction: Direction, driven: NDArray[np.float64], radius: float) -> float:
    """The direction's ``visited`` share (module docstring)."""
    member = _farthest_member(ctx, direction)
    return 0.0 if member is None else retraced_share(member.path, driven, radius)


def driven_before(d: Directions, loop: Loop) -> NDArray[np.float64]:
    """The positions driven before the current segment began (those that count as visited)."""
    starts = loop.host.segment_starts
    return np.asarray(d.driven[: starts[-1] + 1 if starts else 0], dtype=np.float64).reshape(-1, 2)


def gather(
    mapper: OccupancyMapper,
    ctx: StepContext,
    directions: list[Direction],
    driven: NDArray[np.float64],
    config: DirectionsConfig,
) -> dict[int, Evidence]:
    """The evidence of each direction by label; ``driven`` are the positions that count as visited."""
    areas = open_areas(mapper, ctx, directions, config.evidence_reach)
    return {
        direction.label: Evidence(
            area, visited(ctx, direction, driven, config.visited_radius), return_time(ctx, direction)
        )
        for direction, area in zip(directions, areas, strict=True)
    }
