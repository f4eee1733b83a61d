"""The embedded world's measures: Habitat's ObjectNav metrics from the world's own ground truth.

Like habitat-lab's ``Success``, ``SPL``, ``DistanceToGoal`` and ``Collisions`` measures, they follow the agent
from ``reset`` to the end of the episode: geodesic distances come from one Fast-Marching solve to the goal view
points over the world's reachable area (:mod:`drivenav.envs.embedded.terrain`: the one-floor navigable grid's
largest component, or a building's surfaces, up and down its stairs), SPL's d0 is the world's own start distance
(as habitat-lab computes it, never the episode file's), and path length is the executed translation in three
dimensions (habitat-lab's ``SPL`` sums the distances between the agent's successive 3-D positions).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from drivenav import metrics
from drivenav.envs.base import EpisodeMeasures, measured, shows_goal
from drivenav.envs.embedded.terrain import DistanceField
from drivenav.types import Action, Observation, Pose, SimConfig


class EmbeddedMeasures:
    """Success, SPL, distance to goal, path length, collisions and target visibility of one episode."""

    def __init__(self, config: SimConfig) -> None:
        self._config = config
        self._goal_field: DistanceField | None = None
        self._goal_ids: NDArray[np.int64] = np.zeros(0, dtype=np.int64)
        self._positions: list[tuple[float, float, float]] = []
        self._collisions = 0
        self._called_stop = False
        self._target_seen = False

    @property
    def goal_field(self) -> DistanceField:
        """The episode's geodesic distance field to its goal view points."""
        if self._goal_field is None:
            raise RuntimeError("EmbeddedMeasures: reset() first")
        return self._goal_field

    def reset(self, goal_field: DistanceField, start: Pose, goal_ids: Sequence[int] = ()) -> None:
        """Start measuring an episode from ``start`` (world frame) with the distance field to its goals' view
        points over the world's reachable area and its goals' instance ids."""
        self._goal_field = goal_field
        self._goal_ids = np.array(list(goal_ids), dtype=np.int64)
        self._positions = [(start.x, start.y, start.z)]
        self._collisions = 0
        self._called_stop = False
        self._target_seen = False

    def update(self, action: Action | None, pose: Pose, observation: Observation) -> None:
        """After ``action`` (None at reset) the agent is at ``pose`` (world frame) and sees ``observation``."""
        if action is not None:
            self._positions.append((pose.x, pose.y, pose.z))
            self._collisions += int(observation.collided)
            self._called_stop = self._called_stop or action == Action.STOP
        self._target_seen = self._target_seen or shows_goal(observation, self._goal_ids)

    def result(self) -> EpisodeMeasures:
        """The metrics of the episode so far."""
        field = self.goal_field
        distance = field.at(*self._positions[-1])
        geodesic = field.at(*self._positions[0])
        path_length = metrics.path_length(np.asarray(self._positions))
        is_success = metrics.success(self._called_stop, distance, self._config.success_distance)
        return measured(
            success=is_success,
            spl=metrics.spl(is_success, geodesic, path_length),
            distance_to_goal=distance,
            path_length=path_length,
            geodesic_distance=geodesic,
            collisions=self._collisions,
            target_seen=self._target_seen,
        )
