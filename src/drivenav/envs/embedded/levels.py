"""Where an agent can stand and move in a building: its walking surfaces, their navigable cells as one graph, the
motion model over them and geodesic distances through the stairs (docs/floors.md).

Surfaces. Each storey ``j`` gives one *layer* of the building's grid: its free floor (no wall, no blocking object, no
railing, no stairwell) at its elevation, and the staircases rising from it at their ramp's height. A cell of a layer is
*walkable* where it has such a surface. Two horizontally neighbouring surface cells, of one layer or of two (the top of
a staircase and the floor it arrives on), belong to one surface where their heights differ by at most the agent's climb
(habitat-sim's navmesh: 0.2 m). A walkable cell beside a neighbour with surfaces within :data:`SURFACE_BAND` of its own
but none within that step is a *rim* (the low open side of a flight, a stairwell's edge where the stairs are near the
top).

Navigable cells. The agent's centre may stand on a walkable cell when every cell within its radius (the disc of
:meth:`~drivenav.envs.embedded.scene.Scene.navigable_grid`: cell centres within the radius plus half a cell) holds
a walkable cell that is no rim, within :data:`SURFACE_BAND` of its height (a ramp rises at most 0.23 m over the
radius; storeys are metres apart). On one flat storey this is exactly ``Scene.navigable_grid``.

The graph. Navigable cells are nodes; each has up to four neighbours (-x, +x, -y, +y), in its own layer or
another, whose height is within the climb of its own. Its largest connected part is where episodes start.

Distances are the exact fixed point of Sethian's second-order upwind Fast Marching on that graph (a heap-ordered
march, as scikit-fmm's, which the one-floor world uses), with each cell's travel time stretched by
``sqrt(1 + slope^2)`` on a flight, so that a path up the stairs is measured in three dimensions like habitat-sim's
geodesic distance and habitat-lab's path length.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from drivenav.envs.embedded.building import Box3, Building, rect_cells
from drivenav.envs.embedded.geodesic import bilinear_finite
from drivenav.grid import GridSpec
from drivenav.jit import jit

MAX_STEP = 0.2  # metres: the largest height step between neighbouring cells of one surface (habitat's max climb)
SURFACE_BAND = 1.0  # metres: heights this close to the agent's belong to its surface (storeys are >= 2.4 m apart)
COLLISION_EPSILON = 1e-5  # m^2: habitat-sim counts a collision when the squared move falls short of this
Point3 = tuple[float, float, float]


# ----------------------------------------------------------------------------------------------- surfaces


def walkable_heights(building: Building, agent_height: float) -> NDArray[np.float64]:
    """Per layer and cell the walking surface's height above the ground floor, NaN where there is none."""
    grid = building.grid
    gx, gy = grid.cell_centers()
    heights = np.full((len(building.storeys), *grid.shape), np.nan)
    for j, storey in enumerate(building.storeys):
        blocked = storey.plan.obstacle_grid(agent_height) | box_cells(grid, building.railings[j])
        floor = ~blocked & ~building.holes[j] & ~building.stair_cells[j]
        heights[j][floor] = storey.elevation
    for stair in building.stairs:
        layer = heights[stair.lower]
        free = building.storeys[stair.lower].plan.structure == 0
        surface = stair.surface(gx, gy)
        on = np.isfinite(surface) & free
        layer[on] = surface[on]
    return heights


def box_cells(grid: GridSpec, boxes: Sequence[Box3]) -> NDArray[np.bool_]:
    """Cells within half a cell of a box's plan rectangle (as :meth:`Scene.obstacle_grid` rasterises objects)."""
    cells = np.zeros(grid.shape, dtype=bool)
    half = grid.resolution / 2.0
    for box in boxes:
        x0, y0, x1, y1 = box.rect
        cells |= rect_cells(grid, (x0 - half, y0 - half, x1 + half, y1 + half))
    return cells


def slopes(building: Building) -> NDArray[np.float64]:
    """Per layer and cell the surface's gradient (0 off the flights)."""
    gx, gy = building.grid.cell_centers()
    gradient = np.zeros((len(building.storeys), *building.grid.shape))
    for stair in building.stairs:
        gradient[stair.lower] = np.maximum(gradient[stair.lower], stair.slopes(gx, gy))
    return gradient


def disc_offsets(radius: float, resolution: float) -> NDArray[np.int64]:
    """The cell offsets ``(dr, dc)`` within the agent's footprint: centres whose distance less half a cell is at
    most ``radius`` (the clearance rule of :meth:`Scene.navigable_grid`)."""
    reach = math.ceil(radius / resolution + 1.0)
    dr, dc = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    inside = (np.sqrt(dr * dr + dc * dc) - 0.5) * resolution <= radius
    offsets: NDArray[np.int64] = np.stack([dr[inside], dc[inside]], axis=1).astype(np.int64)
    return offsets


@jit("b1[:, :, ::1](f8[:, :, ::1], f8, f8)")
def _rims(heights: NDArray[np.float64], step: float, band: float) -> NDArray[np.bool_]:
    """Walkable cells with a 4-neighbour that has surfaces within ``band`` of theirs but none within ``step`` (a
    higher or lower surface out of the band is another storey's, or a drop the footprint test sees)."""
    layers, rows, cols = heights.shape
    rim = np.zeros(heights.shape, np.bool_)
    for j in range(layers):
        for r in range(rows):
            for c in range(cols):
                h = heights[j, r, c]
                if not math.isfinite(h):
                    continue
                for d in range(4):
                    rr = r + (1 if d == 0 else -1 if d == 1 else 0)
                    cc = c + (1 if d == 2 else -1 if d == 3 else 0)
                    if rr < 0 or rr >= rows or cc < 0 or cc >= cols:
                        continue
                    some, near = False, False
                    for m in range(layers):
                        g = heights[m, rr, cc]
                        if math.isfinite(g) and abs(g - h) <= band:
                            some = True
                            near = near or abs(g - h) <= step
                    if some and not near:
                        rim[j, r, c] = True
    return rim


@jit("b1[:, :, ::1](f8[:, :, ::1], b1[:, :, ::1], i8[:, ::1], f8)")
def _navigable(
    heights: NDArray[np.float64], rim: NDArray[np.bool_], offsets: NDArray[np.int64], band: float
) -> NDArray[np.bool_]:
    """Walkable cells whose every footprint offset holds a walkable, non-rim cell within ``band`` of their height."""
    layers, rows, cols = heights.shape
    navigable = np.zeros(heights.shape, np.bool_)
    for j in range(layers):
        for r in range(rows):
            for c in range(cols):
                h = heights[j, r, c]
                if not math.isfinite(h):
                    continue
                ok = True
                for k in range(offsets.shape[0]):
                    rr, cc = r + offsets[k, 0], c + offsets[k, 1]
                    if rr < 0 or rr >= rows or cc < 0 or cc >= cols:
                        ok = False
                        break
                    found = False
                    for m in range(layers):
                        g = heights[m, rr, cc]
                        if math.isfinite(g) and not rim[m, rr, cc] and abs(g - h) <= band:
                            found = True
                            break
                    if not found:
                        ok = False
                        break
                navigable[j, r, c] = ok
    return navigable


@jit("i4[:, ::1](i4[:, :, ::1], f8[::1], i8[::1], i8[::1], f8)")
def _links(
    index: NDArray[np.int32],
    node_height: NDArray[np.float64],
    node_row: NDArray[np.int64],
    node_col: NDArray[np.int64],
    step: float,
) -> NDArray[np.int32]:
    """Per node its neighbours along -x, +x, -y, +y (-1: none): the node of the neighbouring cell, in any layer,
    whose height is within ``step`` of its own."""
    layers, rows, cols = index.shape
    n = node_height.shape[0]
    links = np.full((n, 4), -1, np.int32)
    for i in range(n):
        r, c, h = node_row[i], node_col[i], node_height[i]
        for d in range(4):
            rr = r + (1 if d == 3 else -1 if d == 2 else 0)
            cc = c + (1 if d == 1 else -1 if d == 0 else 0)
            if rr < 0 or rr >= rows or cc < 0 or cc >= cols:
                continue
            for m in range(layers):
                k = index[m, rr, cc]
                if k >= 0 and abs(node_height[k] - h) <= step:
                    links[i, d] = k
                    break
    return links


# ----------------------------------------------------------------------------------------- the surface graph


@dataclass(frozen=True)
class Node:
    """A navigable cell: its layer, row and column, and its node number."""

    layer: int
    row: int
    col: int
    index: int


class Levels:
    """The navigable surfaces of a building as one graph (the module's docstring), for an agent of ``radius`` and
    ``height`` metres."""

    def __init__(self, building: Building, radius: float, height: float) -> None:
        self.building = building
        self.grid = building.grid
        self.heights = walkable_heights(building, height)
        rim = _rims(self.heights, MAX_STEP, SURFACE_BAND)
        self.navigable = _navigable(self.heights, rim, disc_offsets(radius, self.grid.resolution), SURFACE_BAND)
        layer, row, col = np.nonzero(self.navigable)
        self.index = np.full(self.navigable.shape, -1, np.int32)
        self.index[layer, row, col] = np.arange(len(layer), dtype=np.int32)
        self.node_layer, self.node_row, self.node_col = layer, row.astype(np.int64), col.astype(np.int64)
        self.node_height = np.ascontiguousarray(self.heights[layer, row, col])
        self.links = _links(self.index, self.node_height, self.node_row, self.node_col, MAX_STEP)
        stretch = np.sqrt(1.0 + slopes(building) ** 2)
        self.node_stretch = np.ascontiguousarray(stretch[layer, row, col])

    @property
    def layers(self) -> int:
        return int(self.navigable.shape[0])

    @cached_property
    def reachable(self) -> NDArray[np.bool_]:
        """Per layer and cell: a node of the graph's largest connected part (where episodes start)."""
        n = len(self.node_height)
        reachable = np.zeros(self.navigable.shape, dtype=bool)
        if n == 0:
            return reachable
        source = np.repeat(np.arange(n), 4)
        target = self.links.ravel()
        keep = target >= 0
        graph = coo_matrix((np.ones(int(keep.sum())), (source[keep], target[keep])), shape=(n, n))
        _, labels = connected_components(graph, directed=False)
        largest = np.bincount(labels).argmax()
        member = labels == largest
        reachable[self.node_layer[member], self.node_row[member], self.node_col[member]] = True
        return reachable

    def node_at(self, x: float, y: float, z: float, tolerance: float = MAX_STEP) -> Node | None:
        """The navigable cell under a world point whose surface lies within ``tolerance`` of height ``z`` (the
        nearest one), or None."""
        row, col = self.grid.cell_at(x, y)
        rows, cols = self.grid.shape
        if not (0 <= row < rows and 0 <= col < cols):
            return None
        best: Node | None = None
        gap = tolerance
        for j in range(self.layers):
            k = int(self.index[j, row, col])
            if k >= 0 and abs(self.node_height[k] - z) <= gap:
                best, gap = Node(j, row, col, k), abs(self.node_height[k] - z)
        return best

    def height(self, node: Node) -> float:
        return float(self.node_height[node.index])

    def forward(self, x: float, y: float, z: float, yaw: float, distance: float) -> tuple[Point3, bool]:
        """Move ``distance`` metres along ``yaw`` from a navigable point, sliding along obstacles as the one-floor
        world does (:func:`drivenav.envs.embedded.motion.forward_step`) and following the surface's height:
        the point reached, and whether the move collided by habitat-sim's rule (the squared 3-D distance moved
        falls short of the intended one)."""
        node = self.node_at(x, y, z)
        if node is None:
            return (x, y, z), distance != 0.0
        dx, dy = distance * math.cos(yaw), distance * math.sin(yaw)
        f, z_f = self._free_prefix(x, y, self.height(node), dx, dy)
        if f == 1.0:
            end = (x + dx, y + dy, z_f)
        else:
            bx, by = x + f * dx, y + f * dy
            rx, ry = (1.0 - f) * dx, (1.0 - f) * dy
            fx, zx = self._free_prefix(bx, by, z_f, rx, 0.0)
            fy, zy = self._free_prefix(bx, by, z_f, 0.0, ry)
            slide_x, slide_y = fx * abs(rx), fy * abs(ry)
            if slide_x >= slide_y:
                end = (bx + math.copysign(slide_x, rx), by, zx)
            else:
                end = (bx, by + math.copysign(slide_y, ry), zy)
        moved = (end[0] - x) ** 2 + (end[1] - y) ** 2 + (end[2] - z) ** 2
        return end, moved + COLLISION_EPSILON < distance * distance

    def _free_prefix(self, x: float, y: float, z: float, dx: float, dy: float) -> tuple[float, float]:
        """The largest fraction of the motion whose samples (at most half a cell apart) stay on navigable cells of
        one surface, each within the climb of the last; and the height reached."""
        length = math.hypot(dx, dy)
        if length == 0.0:
            return 0.0, z
        n = max(1, math.ceil(length / (0.5 * self.grid.resolution)))
        reached, height = 0.0, z
        for k in range(1, n + 1):
            node = self.node_at(x + k / n * dx, y + k / n * dy, height)
            if node is None:
                break
            reached, height = k / n, self.height(node)
        return reached, height


# ------------------------------------------------------------------------------------------------ distances


class LevelField:
    """Geodesic distance (metres, along the surfaces and up the stairs) from every node to the nearest of
    ``goals`` (world points with heights, each on the node under it within ``tolerance`` of its height); ``inf``
    where none can be reached. Goal points off the navigable surfaces are ignored."""

    def __init__(self, levels: Levels, goals: Sequence[Point3], tolerance: float = MAX_STEP) -> None:
        self.levels = levels
        sources = {node.index for g in goals if (node := levels.node_at(*g, tolerance)) is not None}
        seeds = np.array(sorted(sources), dtype=np.int64)
        cost = levels.node_stretch * levels.grid.resolution
        self.node_distance = _march_graph(levels.links, np.ascontiguousarray(cost), seeds)

    @cached_property
    def distances(self) -> NDArray[np.float64]:
        """Per layer and cell the distance (``inf`` off the nodes)."""
        grid = np.full(self.levels.navigable.shape, np.inf)
        lv = self.levels
        grid[lv.node_layer, lv.node_row, lv.node_col] = self.node_distance
        return grid

    def at(self, x: float, y: float, z: float = 0.0) -> float:
        """Distance at a world point of height ``z``: bilinear over the finite ones of the four nearest cell
        centres on its surface (cells whose node lies within the climb of ``z``), as the one-floor world's
        :meth:`~drivenav.envs.embedded.geodesic.GeodesicField.at`."""
        return bilinear_finite(self.levels.grid, x, y, lambda row, col: self._cell(row, col, z))

    def _cell(self, row: int, col: int, z: float) -> float:
        lv = self.levels
        for j in range(lv.layers):
            k = int(lv.index[j, row, col])
            if k >= 0 and abs(lv.node_height[k] - z) <= MAX_STEP:
                return float(self.node_distance[k])
        return math.inf


@jit(inline=True)
def _axis_term(
    t: NDArray[np.float64], links: NDArray[np.int32], known: NDArray[np.bool_], i: int, d: int
) -> tuple[float, float, float]:
    """The upwind neighbour of node ``i`` along axis ``d`` (0: x, 1: y): ``(weight, centre, t1)`` of the second-order
    stencil where the neighbour's own neighbour beyond is known and not later, else of the first-order one
    (``weight`` 0: no known neighbour)."""
    best_t, best_k, best_dir = math.inf, -1, -1
    for side in range(2):
        k = links[i, 2 * d + side]
        if k >= 0 and known[k] and t[k] < best_t:
            best_t, best_k, best_dir = t[k], k, 2 * d + side
    if best_k < 0:
        return 0.0, 0.0, math.inf
    beyond = links[best_k, best_dir]
    if beyond >= 0 and known[beyond] and t[beyond] <= best_t:
        return 2.25, (4.0 * best_t - t[beyond]) / 3.0, best_t
    return 1.0, best_t, best_t


@jit(inline=True)
def _solve_node(
    t: NDArray[np.float64], links: NDArray[np.int32], known: NDArray[np.bool_], i: int, cost: float
) -> float:
    """Sethian's second-order upwind update of node ``i`` (first order where the quadratic has no root, one-sided
    where the two axes disagree by more than a cell)."""
    wx, cx, tx = _axis_term(t, links, known, i, 0)
    wy, cy, ty = _axis_term(t, links, known, i, 1)
    for order in range(2):
        if order == 1:  # the first-order stencil of both axes
            wx, cx = (1.0, tx) if wx > 0.0 else (0.0, 0.0)
            wy, cy = (1.0, ty) if wy > 0.0 else (0.0, 0.0)
        a = wx + wy
        b = wx * cx + wy * cy
        c = wx * cx * cx + wy * cy * cy - cost * cost
        disc = b * b - a * c
        if a > 0.0 and disc >= 0.0:
            value = (b + math.sqrt(disc)) / a
            if value >= max(tx if wx > 0.0 else -math.inf, ty if wy > 0.0 else -math.inf):
                return value
    return min(tx, ty) + cost


@jit("f8[::1](i4[:, ::1], f8[::1], i8[::1])")
def _march_graph(links: NDArray[np.int32], cost: NDArray[np.float64], seeds: NDArray[np.int64]) -> NDArray[np.float64]:
    """Heap-ordered Fast Marching over the surface graph from ``seeds`` (time 0), ``cost`` the one-cell travel time
    per node."""
    n = links.shape[0]
    t = np.full(n, np.inf)
    known = np.zeros(n, np.bool_)
    capacity = 4 * n + seeds.shape[0] + 1
    heap_t = np.empty(capacity)
    heap_i = np.empty(capacity, np.int64)
    size = 0
    for s in seeds:
        t[s] = 0.0
        size = _heap_push(heap_t, heap_i, size, 0.0, s)
    while size > 0:
        value, i, size = _heap_pop(heap_t, heap_i, size)
        if known[i] or value > t[i]:
            continue
        known[i] = True
        for d in range(4):
            k = links[i, d]
            if k < 0 or known[k]:
                continue
            candidate = _solve_node(t, links, known, k, cost[k])
            if candidate < t[k]:
                t[k] = candidate
                size = _heap_push(heap_t, heap_i, size, candidate, k)
    return t


@jit(inline=True)
def _heap_push(heap_t: NDArray[np.float64], heap_i: NDArray[np.int64], size: int, value: float, item: int) -> int:
    k = size
    heap_t[k], heap_i[k] = value, item
    while k > 0:
        parent = (k - 1) // 2
        if heap_t[parent] <= heap_t[k]:
            break
        heap_t[parent], heap_t[k] = heap_t[k], heap_t[parent]
        heap_i[parent], heap_i[k] = heap_i[k], heap_i[parent]
        k = parent
    return size + 1


@jit(inline=True)
def _heap_pop(heap_t: NDArray[np.float64], heap_i: NDArray[np.int64], size: int) -> tuple[float, int, int]:
    value, item = heap_t[0], heap_i[0]
    size -= 1
    heap_t[0], heap_i[0] = heap_t[size], heap_i[size]
    k = 0
    while True:
        left, smallest = 2 * k + 1, k
        if left < size and heap_t[left] < heap_t[smallest]:
            smallest = left
        if left + 1 < size and heap_t[left + 1] < heap_t[smallest]:
            smallest = left + 1
        if smallest == k:
            break
        heap_t[smallest], heap_t[k] = heap_t[k], heap_t[smallest]
        heap_i[smallest], heap_i[k] = heap_i[k], heap_i[smallest]
        k = smallest
    return value, int(item), size
