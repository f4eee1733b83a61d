"""What one step's perception gives the decision loop (paper Sec. IV overview, IV-A a).

Every step the depth frame updates the maps, and one weighted-FMM solve of the directions pipeline turns the
frontiers into tracked directions and gives the path to the current goal. :class:`StepContext` holds that
result for the mode handlers; :func:`perceive` makes it and :func:`replan` makes it again, within the same step,
when a decision picks a new goal.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivenav.directions import Direction, DirectionPipeline, DirectionResult
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.types import Pose

Point = tuple[float, float]
Polyline = NDArray[np.float64]


@dataclass
class StepContext:
    """What this step's perception produced (episode frame)."""

    pose: Pose
    snapshot: MapSnapshot
    frontiers: list[Frontier]
    result: DirectionResult
    goal: Point | None
    directions: dict[int, Direction] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.directions = {d.label: d for d in self.result.directions}

    def free(self, x: float, y: float) -> bool:
        """Whether a point is navigable on the robot's map (the planner's line-of-sight test)."""
        row, col = self.snapshot.grid.cell_at(x, y)
        inside = 0 <= row < self.snapshot.navigable.shape[0] and 0 <= col < self.snapshot.navigable.shape[1]
        return bool(inside and self.snapshot.navigable[row, col])

    @property
    def goal_path(self) -> Polyline | None:
        """The weighted-FMM path to this step's goal, if the goal is reachable on the map."""
        return self.result.goal_paths[0] if self.result.goal_paths else None

    def path_along(self, direction: Direction) -> Polyline | None:
        """The path to the goal (the direction's farthest frontier point, Sec. IV-A c), or to the direction's
        nearest reachable frontier when the goal is unreachable."""
        if self.goal_path is not None:
            return self.goal_path
        members = [self.result.paths[f] for f in direction.frontier_ids if f in self.result.paths]
        return min(members, key=lambda p: p.travel_time).path if members else None


def perceive(
    pipeline: DirectionPipeline, pose: Pose, snapshot: MapSnapshot, frontiers: list[Frontier], goal: Point | None
) -> StepContext:
    """One solve of the directions pipeline (Sec. IV-A a-b) from the robot, with the path to ``goal`` if any."""
    goals = [goal] if goal is not None else []
    result = pipeline.update(snapshot, frontiers, (pose.x, pose.y), goals=goals)
    return StepContext(pose, snapshot, frontiers, result, goal)


def replan(pipeline: DirectionPipeline, ctx: StepContext, goal: Point) -> StepContext:
    """The same step's perception with a new goal (only at decision steps: the map has not changed)."""
    if ctx.goal == goal:
        return ctx
    return perceive(pipeline, ctx.pose, ctx.snapshot, ctx.frontiers, goal)
