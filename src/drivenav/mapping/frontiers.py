"""Navigable space and frontiers from the raw maps (paper Sec. IV-A a, after Yamauchi 1997 and VLFM).

A *frontier cell* is a navigable cell with at least one 4-neighbour outside the explored map; frontier
cells are grouped into frontiers by 8-connectivity. Each frontier borders an unexplored *pocket*: the
unexplored cells not within the agent radius of an obstacle (where a robot could still stand), 4-connected
to the frontier's unexplored neighbours, counted inside a window reaching ``pocket_window`` metres beyond the
frontier's bounding box. A closed pocket (the shadow behind furniture seen from both sides) is measured
exactly; unexplored space that opens onto the unknown fills much of the window (about half of at least
4 m x 4 m with the default 2 m), far above VLFM's 1.5 m^2 threshold. Unseen walls do not close a pocket.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drivenav.grid import GridSpec
from drivenav.mapping.kernels import flood_fill, pocket_sizes, raster_components
from drivenav.mapping.types import Frontier

Mask = NDArray[np.bool_]


def component_at(mask: Mask, seed: tuple[int, int], *, eight: bool) -> Mask:
    """The connected component of ``mask`` holding ``seed`` (all False when the seed is not in ``mask``)."""
    i, j = seed
    if not (0 <= i < mask.shape[0] and 0 <= j < mask.shape[1] and mask[i, j]):
        return np.zeros_like(mask)
    return np.asarray(flood_fill(np.ascontiguousarray(mask, dtype=np.bool_), i, j, eight), dtype=np.bool_)


def nearest_in(mask: Mask, seed: tuple[int, int], radius: int) -> tuple[int, int] | None:
    """The ``mask`` cell nearest to ``seed`` within ``radius`` cells (Chebyshev window), or None."""
    i, j = seed
    r0, c0 = max(i - radius, 0), max(j - radius, 0)
    window = mask[r0 : i + radius + 1, c0 : j + radius + 1]
    rows, cols = np.nonzero(window)
    if rows.size == 0:
        return None
    k = int(np.argmin((rows + r0 - i) ** 2 + (cols + c0 - j) ** 2))
    return int(rows[k] + r0), int(cols[k] + c0)


def frontier_cells(explored: Mask, navigable: Mask) -> Mask:
    """Navigable cells with a 4-neighbour outside ``explored`` (cells beyond the array are unexplored)."""
    unexplored = np.pad(~explored, 1, constant_values=True)
    border = unexplored[:-2, 1:-1] | unexplored[2:, 1:-1] | unexplored[1:-1, :-2] | unexplored[1:-1, 2:]
    result: Mask = navigable & border
    return result


def extract_frontiers(
    grid: GridSpec,
    explored: Mask,
    navigable: Mask,
    blocked: Mask,
    *,
    min_area: float,
    pocket_window: float,
    offset: tuple[int, int] = (0, 0),
) -> list[Frontier]:
    """Group frontier cells into frontiers and drop those whose unexplored pocket is below ``min_area`` m^2.

    The masks cover the window of ``grid`` whose first cell is ``offset`` (row, col); reported cells and
    points are in ``grid``. ``blocked`` marks cells within the agent radius of an obstacle; they never belong
    to a pocket. Frontier ids number the kept frontiers in raster order of their first cell, so they are
    stable within one call only.
    """
    cells, starts = raster_components(frontier_cells(explored, navigable))
    passable = ~explored & ~blocked
    margin = math.ceil(pocket_window / grid.resolution)
    areas = pocket_sizes(passable, cells, starts, margin) * grid.resolution**2
    kept = np.flatnonzero(areas >= min_area)
    if kept.size == 0:
        return []
    cells = cells + np.array(offset)
    points = grid.cell_to_world(cells)
    return [
        _make_frontier(n, cells[starts[k] : starts[k + 1]], points[starts[k] : starts[k + 1]], float(areas[k]))
        for n, k in enumerate(kept)
    ]


def _make_frontier(frontier_id: int, cells: NDArray[np.int64], points: NDArray[np.float64], area: float) -> Frontier:
    """Frontier ``frontier_id`` of grid ``cells`` with world ``points``; its waypoint is the member nearest the
    centroid (``np.add.reduce`` directly: the same sums and quotient as ``mean`` and ``sum``, without their Python
    wrappers, which cost more than the arithmetic on a frontier's few dozen cells)."""
    centroid = np.add.reduce(points, axis=0) / len(points)
    k = int(np.add.reduce((points - centroid) ** 2, axis=1).argmin())
    return Frontier(
        frontier_id=frontier_id,
        points=points,
        cells=cells,
        waypoint=(float(points[k, 0]), float(points[k, 1])),
        unexplored_area=float(area),
    )
