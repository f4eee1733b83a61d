"""Navigation metrics, computed as Habitat / HM3D-OVON do, plus the paper's revisit count (Sec. V-C).

Success: STOP called with geodesic distance to the nearest goal view point <= the success distance.
SPL = S * d0 / max(d0, path length) with d0 the start-to-goal geodesic distance and the path the executed
translation (turns add nothing).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

REVISIT_TRAVEL = 5.0  # metres of travel near earlier trajectory for a segment to count as a revisit
REVISIT_RADIUS = 0.5  # metres: "within 0.5 m of the previously traversed 2-D trajectory"
RETRACE_GAP = 1.0  # metres of travel before a stretch of the trajectory counts as "earlier" (ours)


def success(called_stop: bool, distance_to_goal: float, success_distance: float) -> bool:
    """Habitat's ObjectNav success: STOP called closer than the success distance (strictly, as habitat-lab's
    ``Success`` measure compares)."""
    return called_stop and distance_to_goal < success_distance


def spl(is_success: bool, geodesic_distance: float, path_length: float) -> float:
    """Success weighted by path length: ``S * d0 / max(d0, path)``."""
    if not is_success:
        return 0.0
    denominator = max(geodesic_distance, path_length)
    return 1.0 if denominator <= 0.0 else geodesic_distance / denominator


def path_length(positions: NDArray[np.float64]) -> float:
    """Length of the polyline through ``(T, 2)`` positions, or ``(T, 3)`` ones with their heights."""
    if len(positions) < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(positions, axis=0), axis=1)))


def _points(positions: NDArray[np.float64]) -> NDArray[np.float64]:
    """``positions`` as a ``(T, D)`` array: planar points, or points with their heights (a trajectory through a
    building's floors, so that two floors' paths above each other are never near)."""
    points = np.asarray(positions, dtype=np.float64)
    return points.reshape(-1, points.shape[-1] if points.ndim == 2 else 2)


def densify(positions: NDArray[np.float64], spacing: float) -> NDArray[np.float64]:
    """Points along the polyline no farther apart than ``spacing`` (vertices included)."""
    if len(positions) < 2:
        return _points(positions)
    pieces = [positions[:1]]
    for a, b in itertools.pairwise(positions):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing)))
        t = np.arange(1, n + 1)[:, None] / n
        pieces.append(a + t * (b - a))
    return np.concatenate(pieces)


def count_revisits(
    positions: NDArray[np.float64],
    segment_starts: Sequence[int],
    min_travel: float = REVISIT_TRAVEL,
    radius: float = REVISIT_RADIUS,
) -> int:
    """Number of frontier-selection segments that are revisits (paper Sec. V-C).

    ``positions[t]`` is the agent position after ``t`` actions (``positions[0]`` is the start);
    ``segment_starts`` are the indices at which agents started a new segment. A segment counts when the
    translation it makes within ``radius`` of the trajectory traversed before the segment began adds up to at
    least ``min_travel``.
    """
    starts = sorted({s for s in segment_starts if 0 <= s < len(positions)})
    revisits = 0
    for k, start in enumerate(starts):
        end = starts[k + 1] if k + 1 < len(starts) else len(positions) - 1
        if start < 1 or end <= start:
            continue
        earlier = cKDTree(densify(positions[: start + 1], radius / 4.0))
        moves = positions[start : end + 1]
        lengths = np.linalg.norm(np.diff(moves, axis=0), axis=1)
        midpoints = 0.5 * (moves[1:] + moves[:-1])
        near, _ = earlier.query(midpoints, distance_upper_bound=radius + 1e-9)
        if float(np.sum(lengths[np.isfinite(near)])) >= min_travel:
            revisits += 1
    return revisits


def retraced(
    positions: NDArray[np.float64],
    min_travel: float = REVISIT_TRAVEL,
    radius: float = REVISIT_RADIUS,
    gap: float = RETRACE_GAP,
) -> tuple[int, float]:
    """A segmentation-free revisit count: ``(stretches, metres)``.

    A move is *retraced* when its midpoint lies within ``radius`` of the trajectory driven more than ``gap``
    metres of travel earlier. ``stretches`` counts the maximal runs of retraced moves (turns in place neither
    break nor extend a run) of at least ``min_travel`` metres; ``metres`` is the length of all retraced moves. It
    needs no agent's segments, so it measures every method alike (the paper's count, :func:`count_revisits`,
    depends on where each method starts its segments).
    """
    points = _points(positions)
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    moves = np.flatnonzero(steps > 1e-9)
    if len(moves) < 2:
        return 0, 0.0
    dense = densify(points, radius / 4.0)
    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    travelled = np.concatenate([[0.0], np.cumsum(steps)])
    near = np.zeros(len(moves), np.bool_)
    for k, i in enumerate(moves):
        earlier = dense[along <= travelled[i] - gap]
        if len(earlier):
            mid = 0.5 * (points[i] + points[i + 1])
            near[k] = bool(np.min(np.sum((earlier - mid) ** 2, axis=1)) <= radius * radius)
    lengths = steps[moves]
    stretches, run = 0, 0.0
    for is_near, length in zip(near, lengths, strict=True):
        if is_near:
            run += length
            continue
        stretches += run >= min_travel
        run = 0.0
    stretches += run >= min_travel
    return int(stretches), float(lengths[near].sum())
