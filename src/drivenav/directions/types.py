"""Results of the directions core (Sec. IV-A a-b). Positions in the episode world frame (metres), bearings in
radians counter-clockwise from +x, normalised to ``[0, 2 pi)``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class FrontierPath:
    """The weighted-FMM path of one reachable frontier and its path-induced bearing.

    ``target`` is the frontier's reachable cell of least travel time (where backtracking starts);
    ``travel_time`` its FMM arrival time (metres at unit speed, i.e. path length divided by speed);
    ``path`` the backtracked polyline ``(N, 2)`` from the robot to ``target``; ``bearing_point`` the local
    directional point p_i (first crossing of ``path`` with the R_e circle, or the straight-line waypoint in the
    "w/o path bearings" ablation); ``bearing`` the bearing theta_i from the robot to ``bearing_point``;
    ``farthest_point`` the frontier cell farthest (Euclidean) from the robot.
    """

    frontier_id: int
    target: tuple[float, float]
    travel_time: float
    path: NDArray[np.float64]
    bearing_point: tuple[float, float]
    bearing: float
    farthest_point: tuple[float, float]


@dataclass(frozen=True)
class Cluster:
    """One direction of the current step before labelling: frontiers whose bearings span less than tau_theta.

    ``bearing`` is the circular mean of ``member_bearings``; ``waypoints`` ``(K, 2)`` are the member frontiers'
    waypoints (used by the position-based merge), ``points`` ``(M, 2)`` all their cells; ``farthest_point``
    is the member frontier point farthest from the robot (the goal when the direction is followed).
    """

    bearing: float
    frontier_ids: tuple[int, ...]
    member_bearings: tuple[float, ...]
    waypoints: NDArray[np.float64]
    points: NDArray[np.float64]
    farthest_point: tuple[float, float]


@dataclass(frozen=True)
class Direction:
    """A tracked persistent direction D_k = (label, mean bearing) with its supporting frontiers (Eq. 4)."""

    label: int
    bearing: float
    frontier_ids: tuple[int, ...]
    member_bearings: tuple[float, ...]
    waypoints: NDArray[np.float64]
    points: NDArray[np.float64]
    farthest_point: tuple[float, float]

    @staticmethod
    def from_cluster(label: int, cluster: Cluster) -> Direction:
        return Direction(
            label,
            cluster.bearing,
            cluster.frontier_ids,
            cluster.member_bearings,
            cluster.waypoints,
            cluster.points,
            cluster.farthest_point,
        )


@dataclass(frozen=True)
class TrackingUpdate:
    """What one tracking step did to the labels (Sec. IV-A b): ``created`` fresh labels of unmatched clusters,
    ``merged`` fresh labels of position-based merges with the prior labels each retired, ``removed`` prior labels
    left unmatched. A label kept by angular association appears in none of them."""

    created: tuple[int, ...] = ()
    merged: dict[int, tuple[int, ...]] = field(default_factory=dict)
    removed: tuple[int, ...] = ()


@dataclass(frozen=True)
class DirectionResult:
    """One mapping step of the directions core.

    ``directions`` are sorted by label; ``paths`` maps frontier id to its path (reachable frontiers only);
    ``unreachable`` lists the frontier ids dropped because no traversable path reaches them;
    ``timings_ms`` breaks the step down into ``distance_transforms``, ``skeleton``, ``fmm``, ``backtracking``
    (including bearings and goal paths), ``clustering``, ``tracking`` and ``total``; ``tracking`` says which
    labels this step created, merged and removed; ``goal_paths`` holds, per
    goal point passed to the pipeline and in that order, the robot-to-goal polyline ``(N, 2)`` from the same
    FMM solve (ending at the centre of the traversable cell the goal was snapped to), or ``None`` where the goal
    is unreachable.
    """

    directions: tuple[Direction, ...]
    paths: dict[int, FrontierPath]
    unreachable: tuple[int, ...]
    timings_ms: dict[str, float] = field(default_factory=dict)
    goal_paths: tuple[NDArray[np.float64] | None, ...] = ()
    tracking: TrackingUpdate = field(default_factory=TrackingUpdate)
