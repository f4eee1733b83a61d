"""Angular-gap clustering of path-induced bearings (Sec. IV-A b).

Bearings are normalised to ``[0, 2 pi)`` and sorted circularly; the sweep starts right after the largest
circular gap (so no cluster straddles it, and the 0/360 degree seam is irrelevant) and greedily grows a
cluster while its span ``theta_last - theta_first`` stays strictly below ``tau_theta``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drivenav.directions.bearings import TWO_PI, normalize_angle
from drivenav.directions.types import Cluster, FrontierPath
from drivenav.mapping.types import Frontier


def circular_mean(angles: ArrayLike) -> float:
    """Circular mean in ``[0, 2 pi)`` (the direction of the mean unit vector)."""
    a = np.asarray(angles, dtype=np.float64)
    return normalize_angle(math.atan2(float(np.sin(a).sum()), float(np.cos(a).sum())))


def circular_distance(a: float, b: float) -> float:
    """Delta(a, b) = min(|a - b|, 2 pi - |a - b|) for angles given in ``[0, 2 pi)`` (Eq. 5)."""
    d = abs(normalize_angle(a) - normalize_angle(b))
    return min(d, TWO_PI - d)


def cluster_bearings(bearings: ArrayLike, span: float) -> list[NDArray[np.int64]]:
    """Partition bearing indices into clusters each spanning less than ``span`` radians.

    Returns index arrays into ``bearings``, each in circular order, the clusters in sweep order starting after
    the largest gap. Ties in the largest gap go to the first in ascending-bearing order.
    """
    b = np.mod(np.asarray(bearings, dtype=np.float64).reshape(-1), TWO_PI)
    n = b.size
    if n == 0:
        return []
    order = np.argsort(b, kind="stable")
    sorted_b = b[order]
    gaps = np.diff(sorted_b, append=sorted_b[0] + TWO_PI)
    first = (int(np.argmax(gaps)) + 1) % n
    order = np.roll(order, -first)
    offset = b[order] - b[order[0]]
    unwrapped = np.where(offset < 0.0, offset + TWO_PI, offset)  # angle swept since the first bearing
    groups: list[NDArray[np.int64]] = []
    start = 0
    for k in range(1, n + 1):
        if k == n or unwrapped[k] - unwrapped[start] >= span:
            groups.append(order[start:k].astype(np.int64))
            start = k
    return groups


def build_clusters(
    paths: Sequence[FrontierPath],
    frontiers: Mapping[int, Frontier],
    robot_xy: Sequence[float],
    span: float,
) -> list[Cluster]:
    """Cluster the frontiers' bearings and gather each cluster's members, waypoints, points and goal."""
    robot = np.asarray(robot_xy, dtype=np.float64)
    clusters: list[Cluster] = []
    for group in cluster_bearings([p.bearing for p in paths], span):
        members = [paths[k] for k in group]
        bearings = tuple(p.bearing for p in members)
        ids = tuple(p.frontier_id for p in members)
        waypoints = np.array([frontiers[i].waypoint for i in ids], dtype=np.float64).reshape(-1, 2)
        points = np.concatenate([frontiers[i].points for i in ids]).reshape(-1, 2)
        goals = np.array([p.farthest_point for p in members], dtype=np.float64)
        far = goals[int(np.argmax(np.hypot(*(goals - robot).T)))]
        clusters.append(
            Cluster(circular_mean(bearings), ids, bearings, waypoints, points, (float(far[0]), float(far[1])))
        )
    return clusters
