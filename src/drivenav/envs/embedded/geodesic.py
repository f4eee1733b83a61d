"""Geodesic distances on the navigable grid, the embedded stand-in for Habitat's navmesh queries.

One Fast-Marching solve (scikit-fmm) from a set of goal points gives the shortest-path distance from every
navigable cell to the nearest goal; queries interpolate bilinearly between cell centres. This is what the
metrics use (distance to goal, SPL's d0) and what the oracle agent descends.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import skfmm
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.directions.speed import crop_window
from drivenav.grid import GridSpec


def largest_component(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The largest 4-connected component of ``mask`` (all False if ``mask`` is empty).

    The one connectivity rule of the embedded world (object placement, episode starts and view points, the
    measures): cells that touch only at a corner are not connected. That is the connectivity of the world's
    distances: the Fast-Marching solve of :class:`GeodesicField` steps between the four axis neighbours only, so
    every cell of a 4-connected component has a finite distance to every goal in it, and a start and goal in it
    never yield a null distance to goal or SPL. A body moving through a corner contact would have to cross one of
    the two blocked cells beside it; :func:`drivenav.envs.embedded.motion.forward_step` checks its segment at samples
    half a cell apart, so a step nearly along the diagonal can still slip through (pockets joined only by a corner are
    at most a few square metres of the shared maps). 8-connectivity would add those pockets, with infinite
    distances. The golden episodes (procedural houses) are the same under either rule; map episodes are not.
    """
    labels, count = ndimage.label(mask)
    if count == 0:
        return np.zeros_like(mask)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    largest: NDArray[np.bool_] = labels == int(np.argmax(sizes))
    return largest


class GeodesicField:
    """Shortest-path distance (metres) over ``navigable`` to the nearest of ``goals`` (world points).

    Cells that cannot reach a goal hold ``inf`` and goal cells 0 (also where goals fill every cell they reach,
    which leaves Fast Marching no front to start from). Goal points off the navigable grid are ignored; if none is
    left every distance is ``inf``.
    """

    def __init__(self, navigable: NDArray[np.bool_], grid: GridSpec, goals: Sequence[tuple[float, float]]) -> None:
        self.grid = grid
        self.distances = _goal_distances(navigable, grid, goals)

    def at(self, x: float, y: float) -> float:
        """Distance at a world point: bilinear over the finite ones of the four nearest cell centres."""
        return bilinear_finite(self.grid, x, y, lambda row, col: float(self.distances[row, col]))


def bilinear_finite(grid: GridSpec, x: float, y: float, value: Callable[[int, int], float]) -> float:
    """Bilinear interpolation at a world point of the cell values ``value(row, col)`` of the four nearest cell
    centres on the grid, over the finite ones (``inf`` where none is): how the world reads a distance field between
    cell centres."""
    res = grid.resolution
    fx = (x - grid.origin[0]) / res - 0.5
    fy = (y - grid.origin[1]) / res - 0.5
    c0, r0 = math.floor(fx), math.floor(fy)
    tx, ty = fx - c0, fy - r0
    total, weight_sum = 0.0, 0.0
    for dr, dc, w in (
        (0, 0, (1 - tx) * (1 - ty)),
        (0, 1, tx * (1 - ty)),
        (1, 0, (1 - tx) * ty),
        (1, 1, tx * ty),
    ):
        r, c = r0 + dr, c0 + dc
        if w <= 0.0 or not (0 <= r < grid.shape[0] and 0 <= c < grid.shape[1]):
            continue
        cell = value(r, c)
        if math.isfinite(cell):
            total += w * cell
            weight_sum += w
    return total / weight_sum if weight_sum > 0.0 else math.inf


def _goal_distances(
    navigable: NDArray[np.bool_], grid: GridSpec, goals: Sequence[tuple[float, float]]
) -> NDArray[np.float64]:
    """:class:`GeodesicField`'s distances. The solve runs on the bounding box of the navigable cells (one cell
    wider), and the grid-sized result is made after it, when scikit-fmm's temporaries are freed (the worker-memory
    goal)."""
    cells = grid.world_to_cell(np.asarray(goals, dtype=np.float64).reshape(-1, 2))
    cells = cells[grid.contains(cells)]
    cells = cells[navigable[cells[:, 0], cells[:, 1]]]
    if len(cells) == 0:
        return np.full(grid.shape, np.inf)
    box = crop_window(grid, navigable, margin=1)
    window = navigable[box.r0 : box.r1, box.c0 : box.c1]
    goal = np.zeros(window.shape, dtype=bool)
    goal[cells[:, 0] - box.r0, cells[:, 1] - box.c0] = True
    if not (ndimage.binary_dilation(goal) & window & ~goal).any():  # no free cell beside a goal: none to solve
        distances = np.full(grid.shape, np.inf)
        distances[cells[:, 0], cells[:, 1]] = 0.0
        return distances
    solved = _solve(goal, window, grid.resolution)
    distances = np.full(grid.shape, np.inf)
    distances[box.r0 : box.r1, box.c0 : box.c1] = solved
    return distances


def _solve(goal: NDArray[np.bool_], window: NDArray[np.bool_], resolution: float) -> NDArray[np.float64]:
    """scikit-fmm's distance from ``goal`` over ``window``'s cells (``inf`` off them), plus half a cell (to a goal
    cell's centre rather than its edge), clipped at 0; computed in place once the solver's arrays are freed."""
    solved = skfmm.distance(np.ma.MaskedArray(np.where(goal, -1.0, 1.0), ~window), dx=resolution)
    values: NDArray[np.float64] = np.ma.filled(solved, np.inf)
    del solved
    values += 0.5 * resolution
    return np.maximum(values, 0.0, out=values)
