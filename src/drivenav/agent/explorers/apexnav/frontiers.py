"""ApexNav's frontier scores, the statistic that switches its mode, and frontier identity over steps
(``exploration_manager.cpp``, ``frontier_map2d.cpp``; constants:
:class:`~drivenav.agent.explorers.apexnav.config.ApexnavConfig`).

* Score (``getSortedSemanticFrontiers``): a frontier is split along its principal axis until every cell lies within
  ``piece_radius`` of its piece's centroid (ApexNav's frontiers are those pieces); a piece scores the largest
  value-map value of the ``(2k + 1)^2`` cells around its centroid, ``k = score_half_width / resolution`` (5 x 5 at
  0.05 m), leaving out obstacle and inflated cells (explored, not navigable). Our frontiers are not split into
  candidates of their own -- each keeps the path the weighted-FMM solve gives it -- so a frontier scores its best
  piece.
* Statistic (``calcSemanticFrontierInfo``): over the candidates' scores, the mean ``m``, the ratio ``r = max / m``
  (0 when ``m <= 0``) and the population standard deviation ``sigma``. Semantic mode iff ``sigma > sigma_t`` and
  ``r > r_t`` (``hybridExplorePolicy``; re-tested at every decision, no hysteresis), keeping the frontiers with
  ``s >= max(r_t m, p max)`` (``findTSPTourPolicy``).
* Identity: a frontier is its cells. Two frontiers of different steps are the same when they share at least
  ``1 - frontier_changed`` of the larger's cells (ApexNav renews a frontier once 20 % of its cells stopped being
  frontier): how dormancy outlives a step and how the explorer tells that the frontiers did not change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.fusion import Keys, centre_keys
from drivenav.grid import GridSpec
from drivenav.mapping.types import Frontier, MapSnapshot

FloatMap = NDArray[np.float64]


def pieces(points: NDArray[np.float64], radius: float) -> list[NDArray[np.float64]]:
    """``points`` split in two along their principal axis, recursively, until every piece's points lie within
    ``radius`` of its centroid (``frontier_map2d.cpp``'s PCA split), in a fixed order."""
    done, todo = [], [points]
    while todo:
        part = todo.pop()
        dx, dy = (part - part.mean(axis=0)).T
        if len(part) < 2 or float(np.max(dx * dx + dy * dy)) <= radius * radius:
            done.append(part)
            continue
        angle = 0.5 * math.atan2(2.0 * float(dx @ dy), float(dx @ dx - dy @ dy))  # the principal axis
        side = dx * math.cos(angle) + dy * math.sin(angle) >= 0.0
        if side.all() or not side.any():
            done.append(part)
            continue
        todo += [part[~side], part[side]]
    return done


def blocked_cells(snapshot: MapSnapshot) -> NDArray[np.bool_]:
    """The cells a frontier score leaves out: obstacles and their inflation (explored, not navigable)."""
    blocked: NDArray[np.bool_] = snapshot.explored & ~snapshot.navigable
    return blocked


def piece_score(
    centres: NDArray[np.float64], value: FloatMap, blocked: NDArray[np.bool_], grid: GridSpec, half_width: float
) -> float:
    """The best score of pieces with centroids ``centres`` ``(P, 2)`` on the value map ``value`` (on ``grid``, with
    ``blocked`` of :func:`blocked_cells`; module docstring); 0 where no window has an open cell."""
    k = round(half_width / grid.resolution)
    best = -math.inf
    for row, col in grid.world_to_cell(centres).tolist():
        r0, c0 = max(row - k, 0), max(col - k, 0)
        window = value[r0 : row + k + 1, c0 : col + k + 1]
        open_cells = ~blocked[r0 : row + k + 1, c0 : col + k + 1]
        if open_cells.any():
            best = max(best, float(window[open_cells].max()))
    return best if math.isfinite(best) else 0.0


def centroids(points: NDArray[np.float64], radius: float) -> NDArray[np.float64]:
    """The centroids of the frontier's pieces (:func:`pieces`), ``(P, 2)``."""
    return np.array([part.mean(axis=0) for part in pieces(points, radius)])


@dataclass(frozen=True)
class Statistic:
    """The scores' mean, max / mean (0 for a mean <= 0) and population standard deviation."""

    mean: float
    ratio: float
    sigma: float

    @staticmethod
    def of(scores: NDArray[np.float64]) -> Statistic:
        mean = float(scores.mean())
        return Statistic(mean, float(scores.max()) / mean if mean > 0.0 else 0.0, float(scores.std()))

    def semantic(self, sigma_threshold: float, ratio_threshold: float) -> bool:
        """ApexNav's switch: semantic mode iff the scores spread (``sigma``) and one stands out (``ratio``)."""
        return self.sigma > sigma_threshold and self.ratio > ratio_threshold


def high_value(scores: NDArray[np.float64], statistic: Statistic, ratio_threshold: float, share: float) -> list[int]:
    """The indices of the scores at least ``max(ratio_threshold * mean, share * max)`` (semantic mode's set)."""
    floor = max(ratio_threshold * statistic.mean, share * float(scores.max()))
    return [i for i, score in enumerate(scores.tolist()) if score >= floor]


class FrontierCells:
    """The cells of some frontiers as lattice keys (``parts``), with which frontier each key belongs to (module
    docstring)."""

    def __init__(self, parts: list[Keys]) -> None:
        self.parts = parts
        self.sizes = np.array([len(k) for k in parts], dtype=np.int64)
        self.keys: Keys = np.concatenate(parts) if parts else np.empty(0, dtype=np.int64)
        self.owner = np.repeat(np.arange(len(parts)), self.sizes)

    @staticmethod
    def of(frontiers: list[Frontier], resolution: float) -> FrontierCells:
        """The frontiers' cells (their points are the centres of distinct cells of the map)."""
        if not frontiers:
            return FrontierCells([])
        keys = centre_keys(np.concatenate([f.points for f in frontiers]), resolution)
        return FrontierCells(np.split(keys, np.cumsum([len(f.points) for f in frontiers[:-1]])))

    def __len__(self) -> int:
        return len(self.parts)

    def pick(self, indices: list[int]) -> FrontierCells:
        return FrontierCells([self.parts[i] for i in indices])

    def plus(self, other: FrontierCells) -> FrontierCells:
        return FrontierCells([*self.parts, *other.parts])

    def matches(self, other: FrontierCells, changed: float) -> NDArray[np.bool_]:
        """``(len(self), len(other))``: which frontiers of the two sets are the same frontier (``self``: one step's
        frontiers, whose cells are distinct; ``other``'s may repeat)."""
        shared = np.zeros((len(self), len(other)), dtype=np.int64)
        order = np.argsort(self.keys, kind="stable")
        ordered = self.keys[order]
        at = np.minimum(np.searchsorted(ordered, other.keys), max(len(ordered) - 1, 0))
        hit = ordered[at] == other.keys if len(ordered) else np.zeros(len(other.keys), dtype=np.bool_)
        np.add.at(shared, (self.owner[order[at[hit]]], other.owner[hit]), 1)
        larger = np.maximum(self.sizes[:, None], other.sizes[None, :])
        same: NDArray[np.bool_] = (shared >= (1.0 - changed) * larger) & (larger > 0)
        return same
