"""Temporal association of directions across mapping steps (Sec. IV-A b, "temporal association").

Stage 1, position-based merge: a current cluster whose frontier waypoints coincide (within
``DirectionConfig.merge_tolerance``) with waypoints of two or more previous directions retires those labels and
receives a fresh one. Stage 2, angular association: the remaining (cluster, previous direction) pairs are ranked
by the circular distance Delta of their bearings (Eq. 5) and matched greedily; a match keeps the previous label
and takes the new bearing, unmatched clusters get fresh labels, unmatched previous directions are dropped.

Not in the paper: pairs farther apart than ``DirectionConfig.association_gate`` (default 90 degrees) are never
matched, so a direction that vanished on one side is not "continued" by an unrelated one appearing on the
opposite side; set it to pi to disable the gate. Labels are ints, handed out in increasing order from 0 and
never reused within an episode (until :meth:`DirectionTracker.reset`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from drivenav.directions.clustering import circular_distance
from drivenav.directions.types import Cluster, Direction, TrackingUpdate
from drivenav.paper import DirectionConfig


def waypoints_coincide(a: NDArray[np.float64], b: NDArray[np.float64], tolerance: float) -> bool:
    """Whether some waypoint of ``a`` ``(K, 2)`` lies within ``tolerance`` of some waypoint of ``b``."""
    if a.size == 0 or b.size == 0:
        return False
    return bool(_close_pairs(a, b, tolerance).any())


def _close_pairs(a: NDArray[np.float64], b: NDArray[np.float64], tolerance: float) -> NDArray[np.bool_]:
    """``[i, j]``: whether point ``a[i]`` lies within ``tolerance`` of point ``b[j]``."""
    diff = a[:, None, :] - b[None, :, :]
    return np.asarray(np.einsum("ijk,ijk->ij", diff, diff) <= tolerance * tolerance, dtype=np.bool_)


def coinciding(
    a: Sequence[NDArray[np.float64]], b: Sequence[NDArray[np.float64]], tolerance: float
) -> NDArray[np.bool_]:
    """``[k, m]``: :func:`waypoints_coincide` of ``a[k]`` and ``b[m]``, every pair from one array operation (the
    same arithmetic per pair of points)."""
    out = np.zeros((len(a), len(b)), dtype=np.bool_)
    a_counts = np.array([len(w) for w in a], dtype=np.int64)
    b_counts = np.array([len(w) for w in b], dtype=np.int64)
    if not (a_counts.any() and b_counts.any()):
        return out
    close = _close_pairs(np.concatenate(a).reshape(-1, 2), np.concatenate(b).reshape(-1, 2), tolerance)
    rows = np.flatnonzero(a_counts)
    cols = np.flatnonzero(b_counts)
    by_row = np.logical_or.reduceat(close, (np.cumsum(a_counts) - a_counts)[rows], axis=0)
    out[np.ix_(rows, cols)] = np.logical_or.reduceat(by_row, (np.cumsum(b_counts) - b_counts)[cols], axis=1)
    return out


class DirectionTracker:
    """Keeps persistent direction labels across steps; see the module docstring for the rules."""

    def __init__(self, config: DirectionConfig) -> None:
        self._config = config
        self._directions: tuple[Direction, ...] = ()
        self._next_label = 0
        self.last_update = TrackingUpdate()

    @property
    def directions(self) -> tuple[Direction, ...]:
        """The directions after the last update, sorted by label."""
        return self._directions

    def reset(self) -> None:
        """Forget all directions and restart labels at 0 (a new episode)."""
        self._directions = ()
        self._next_label = 0
        self.last_update = TrackingUpdate()

    def update(self, clusters: Sequence[Cluster]) -> tuple[Direction, ...]:
        """Label this step's clusters; returns the tracked directions sorted by label."""
        labels: list[int | None] = [None] * len(clusters)
        merged = self._merge_by_position(clusters, labels)
        retired = {label for parents in merged.values() for label in parents}
        self._associate_by_angle(clusters, labels, retired)
        created = [k for k, label in enumerate(labels) if label is None]
        final = [self._fresh_label() if label is None else label for label in labels]
        kept = set(final)
        removed = tuple(d.label for d in self._directions if d.label not in kept and d.label not in retired)
        self.last_update = TrackingUpdate(tuple(final[k] for k in created), merged, removed)
        directions = [Direction.from_cluster(label, c) for label, c in zip(final, clusters, strict=True)]
        self._directions = tuple(sorted(directions, key=lambda d: d.label))
        return self._directions

    def _fresh_label(self) -> int:
        label = self._next_label
        self._next_label += 1
        return label

    def _merge_by_position(self, clusters: Sequence[Cluster], labels: list[int | None]) -> dict[int, tuple[int, ...]]:
        """Stage 1; fills ``labels`` for merged clusters and returns each fresh label's retired previous labels."""
        merged: dict[int, tuple[int, ...]] = {}
        retired: set[int] = set()
        close = coinciding(
            [c.waypoints for c in clusters], [d.waypoints for d in self._directions], self._config.merge_tolerance
        )
        for k in range(len(clusters)):
            hits = [d.label for m, d in enumerate(self._directions) if d.label not in retired and close[k, m]]
            if len(hits) >= 2:
                retired.update(hits)
                labels[k] = label = self._fresh_label()
                merged[label] = tuple(hits)
        return merged

    def _associate_by_angle(self, clusters: Sequence[Cluster], labels: list[int | None], retired: set[int]) -> None:
        """Stage 2: greedy matching by increasing Delta, within the association gate."""
        previous = [d for d in self._directions if d.label not in retired]
        pairs = sorted(
            (circular_distance(c.bearing, d.bearing), k, m)
            for k, c in enumerate(clusters)
            if labels[k] is None
            for m, d in enumerate(previous)
        )
        used: set[int] = set()
        for delta, k, m in pairs:
            if delta > self._config.association_gate:
                break
            if labels[k] is None and m not in used:
                labels[k] = previous[m].label
                used.add(m)
