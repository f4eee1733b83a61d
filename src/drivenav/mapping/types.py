"""Types shared by mapping and directions: the map state and frontiers (all in the episode frame)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.grid import GridSpec
from drivenav.types import Pose


@dataclass(frozen=True)
class Frontier:
    """A frontier: a connected boundary between explored navigable space and unexplored space.

    ``points`` are the world ``(x, y)`` of all its cells ``(N, 2)``; ``cells`` the same as ``(row, col)``;
    ``waypoint`` is its representative point (a member cell closest to the centroid); ``unexplored_area`` is the
    area in m^2 of the unexplored pocket it borders (used to drop tiny frontiers).
    """

    frontier_id: int
    points: NDArray[np.float64]
    cells: NDArray[np.int64]
    waypoint: tuple[float, float]
    unexplored_area: float


@dataclass(frozen=True)
class MapSnapshot:
    """A read-only view of the maps at one step, the input of the directions core.

    ``obstacle``: cells with an obstacle observation; ``explored``: cells seen (the component containing the
    agent); ``navigable``: explored free cells farther than the agent radius from every obstacle.
    """

    grid: GridSpec
    obstacle: NDArray[np.bool_]
    explored: NDArray[np.bool_]
    navigable: NDArray[np.bool_]


@dataclass(frozen=True)
class Rays:
    """The 2-D ray cast of one depth frame (:class:`~drivenav.mapping.occupancy.OccupancyMapper`): from ``pose``,
    rays at ``angles`` off its heading (radians, counter-clockwise, ascending and evenly spaced) saw free space out
    to ``ranges`` (horizontal metres; 0 where the column saw something too close to measure)."""

    pose: Pose
    angles: NDArray[np.float64]
    ranges: NDArray[np.float64]
