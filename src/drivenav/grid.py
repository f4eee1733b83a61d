"""Metric 2-D grids shared by the world, the maps and the planners.

Convention (used everywhere in drivenav): a grid array is indexed ``[row, col]``; row ``i`` grows with world
``y`` and column ``j`` with world ``x``. Cell ``(i, j)`` covers ``x in [ox + j*res, ox + (j+1)*res)`` and
``y in [oy + i*res, oy + (i+1)*res)`` where ``(ox, oy)`` is :attr:`GridSpec.origin`, the world position of the
lower-left corner of cell ``(0, 0)`` -- the same meaning as ``origin`` in a ROS map_server YAML. (ROS images
store the top row first, so loaders flip them vertically.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class GridSpec:
    """Geometry of a metric grid: cell size in metres, world origin of cell (0, 0), shape (rows, cols)."""

    resolution: float
    origin: tuple[float, float]
    shape: tuple[int, int]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """World bounds ``(xmin, xmax, ymin, ymax)``."""
        ox, oy = self.origin
        rows, cols = self.shape
        return ox, ox + cols * self.resolution, oy, oy + rows * self.resolution

    def world_to_cell(self, xy: ArrayLike) -> NDArray[np.int64]:
        """World ``(..., 2)`` points ``(x, y)`` to integer cells ``(..., 2)`` as ``(row, col)``."""
        p = np.asarray(xy, dtype=np.float64)
        out = np.empty((*p.shape[:-1], 2), dtype=np.int64)
        out[..., 0] = np.floor((p[..., 1] - self.origin[1]) / self.resolution)
        out[..., 1] = np.floor((p[..., 0] - self.origin[0]) / self.resolution)
        return out

    def cell_at(self, x: float, y: float) -> tuple[int, int]:
        """The ``(row, col)`` holding one world point: :meth:`world_to_cell` for a single point, without building
        arrays (the planner and the mappers ask this thousands of times per episode; same IEEE operations, same
        cells)."""
        return (
            math.floor((y - self.origin[1]) / self.resolution),
            math.floor((x - self.origin[0]) / self.resolution),
        )

    def cell_to_world(self, rc: ArrayLike) -> NDArray[np.float64]:
        """Cells ``(..., 2)`` as ``(row, col)`` to the world ``(x, y)`` of their centres."""
        c = np.asarray(rc, dtype=np.float64)
        out = np.empty((*c.shape[:-1], 2), dtype=np.float64)
        out[..., 0] = self.origin[0] + (c[..., 1] + 0.5) * self.resolution
        out[..., 1] = self.origin[1] + (c[..., 0] + 0.5) * self.resolution
        return out

    def contains(self, rc: ArrayLike) -> NDArray[np.bool_]:
        """Whether cells ``(..., 2)`` lie inside the grid."""
        c = np.asarray(rc)
        return (c[..., 0] >= 0) & (c[..., 0] < self.shape[0]) & (c[..., 1] >= 0) & (c[..., 1] < self.shape[1])

    def cell_centers(
        self, rows: slice = slice(None), cols: slice = slice(None)
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World ``x`` and ``y`` of every cell centre, each of shape :attr:`shape`; of the block ``[rows, cols]``
        only when given (the same values as the whole grid's there)."""
        xs = self.origin[0] + (np.arange(self.shape[1])[cols] + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(self.shape[0])[rows] + 0.5) * self.resolution
        gx, gy = np.meshgrid(xs, ys)
        return gx, gy

    def block_covering(self, points: ArrayLike, margin: float = 0.0) -> tuple[slice, slice]:
        """The ``(rows, cols)`` block holding every cell whose centre lies within ``margin`` of the bounding box of
        the world ``points`` ``(N, 2)`` (one cell of slack on each side, clipped to the grid)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if p.size == 0:
            return slice(0, 0), slice(0, 0)
        lo = (p.min(axis=0) - margin - np.asarray(self.origin)) / self.resolution - 1.5
        hi = (p.max(axis=0) + margin - np.asarray(self.origin)) / self.resolution + 1.5
        c0, r0 = (max(math.floor(v), 0) for v in lo)
        c1, r1 = (math.ceil(v) + 1 for v in hi)
        return slice(r0, min(max(r1, r0), self.shape[0])), slice(c0, min(max(c1, c0), self.shape[1]))


def wrap_angle(angle: float) -> float:
    """Map an angle in radians to ``(-pi, pi]``."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped
