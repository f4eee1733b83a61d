"""Hand-built map snapshots and a minimal frontier extractor, for the directions tests and benchmark.

This is *not* the mapping module's frontier extraction; it only turns a ground-truth free-space mask and an
explored mask into the :class:`MapSnapshot` / :class:`Frontier` contract so that the directions core can be
exercised without a simulator. Frontier cells here are navigable cells 4-adjacent to unexplored cells, grouped
into 8-connected components.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from drivenav.grid import GridSpec
from drivenav.mapping.types import Frontier, MapSnapshot

_FOUR = ndimage.generate_binary_structure(2, 1)
_EIGHT = ndimage.generate_binary_structure(2, 2)


def make_snapshot(
    free: NDArray[np.bool_],
    explored: NDArray[np.bool_],
    resolution: float = 0.05,
    origin: tuple[float, float] = (0.0, 0.0),
    inflation: float = 0.0,
) -> MapSnapshot:
    """Obstacles are explored non-free cells; navigable cells are explored free cells farther than
    ``inflation`` metres from every obstacle."""
    free = np.asarray(free, dtype=np.bool_)
    explored = np.asarray(explored, dtype=np.bool_)
    obstacle = explored & ~free
    clearance = ndimage.distance_transform_edt(~obstacle) * resolution
    navigable = explored & free & (clearance > inflation)
    return MapSnapshot(GridSpec(resolution, origin, free.shape), obstacle, explored, navigable)


def extract_frontiers(snapshot: MapSnapshot, min_cells: int = 1) -> list[Frontier]:
    """Navigable cells 4-adjacent to unexplored space, as 8-connected frontiers of at least ``min_cells``."""
    unexplored = ~snapshot.explored
    edge = snapshot.navigable & ndimage.binary_dilation(unexplored, _FOUR)
    components, count = ndimage.label(edge, _EIGHT)
    pockets, _ = ndimage.label(unexplored, _FOUR)
    pocket_sizes = np.bincount(pockets.ravel())
    area = snapshot.grid.resolution**2
    frontiers: list[Frontier] = []
    for label in range(1, count + 1):
        cells = np.argwhere(components == label).astype(np.int64)
        if len(cells) < min_cells:
            continue
        points = snapshot.grid.cell_to_world(cells)
        centre = points.mean(axis=0)
        waypoint = points[int(np.argmin(np.hypot(*(points - centre).T)))]
        touching = ndimage.binary_dilation(components == label, _FOUR) & unexplored
        pocket_ids = np.unique(pockets[touching])
        frontiers.append(
            Frontier(
                frontier_id=len(frontiers),
                points=points,
                cells=cells,
                waypoint=(float(waypoint[0]), float(waypoint[1])),
                unexplored_area=float(pocket_sizes[pocket_ids].sum() * area),
            )
        )
    return frontiers


def rect(mask: NDArray[np.bool_], x0: float, y0: float, x1: float, y1: float, res: float = 0.05) -> None:
    """Set the cells whose centres lie in the world rectangle ``[x0, x1] x [y0, y1]`` (origin at 0, 0)."""
    c0, c1 = int(np.ceil(x0 / res - 0.5)), int(np.floor(x1 / res - 0.5)) + 1
    r0, r1 = int(np.ceil(y0 / res - 0.5)), int(np.floor(y1 / res - 0.5)) + 1
    mask[max(r0, 0) : max(r1, 0), max(c0, 0) : max(c1, 0)] = True
