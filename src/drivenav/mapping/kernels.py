"""Numba kernels of the mapper. Callers pass plain numpy arrays; the typed wrappers live in the callers.

All grids follow :mod:`drivenav.grid`: ``[row, col]``, row along world ``y``, column along world ``x``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drivenav.jit import jit

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
Mask = NDArray[np.bool_]


@jit(
    "i8(f4[:, ::1], i8[::1], i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], b1[:, ::1], b1[:, ::1], i8[:, ::1], f8[::1])",
)
def project_depth(
    depth: NDArray[np.float32],
    rows: I64,
    cols: I64,
    camera: F64,
    band: F64,
    pose: F64,
    grid: F64,
    obstacle: Mask,
    inflated: Mask,
    disk: I64,
    col_range: F64,
) -> int:
    """Back-project subsampled depth pixels, mark obstacles, and find each column's free range.

    ``camera`` = (fx, fy, cx, cy, camera height), ``band`` = (min depth, max depth, clip epsilon, min obstacle
    height, max obstacle height), ``pose`` = (x, y, yaw), ``grid`` = (origin x, origin y, resolution).
    Newly marked obstacle cells stamp ``disk`` (row/col offsets) into ``inflated``. ``col_range[k]``
    receives the horizontal distance to which column ``cols[k]`` saw free space: the nearest obstacle (0 where
    something is closer than the minimum depth), else the farthest floor-level evidence. Returns the number of
    new obstacle cells.
    """
    fx, fy, cx, cy, cam_h = camera[0], camera[1], camera[2], camera[3], camera[4]
    min_d, max_d, eps, min_h, max_h = band[0], band[1], band[2], band[3], band[4]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    ox, oy, res = grid[0], grid[1], grid[2]
    n_rows, n_cols = obstacle.shape
    added = 0
    for k in range(cols.shape[0]):
        u = cols[k]
        kx = (cx - u) / fx
        norm = math.sqrt(1.0 + kx * kx)
        hit = math.inf
        seen = 0.0
        for v in rows:
            z = depth[v, u]
            if not (math.isfinite(z) and z > 0.0):
                continue
            if z <= min_d + eps:
                hit = 0.0
                continue
            ky = (cy - v) / fy
            if z >= max_d - eps:
                if cam_h + ky * max_d <= max_h:
                    seen = max(seen, max_d * norm)
                continue
            h = cam_h + ky * z
            if h > max_h:
                continue
            seen = max(seen, z * norm)
            if h < min_h:
                continue
            hit = min(hit, z * norm)
            x = pose[0] + c * z - s * z * kx
            y = pose[1] + s * z + c * z * kx
            i = math.floor((y - oy) / res)
            j = math.floor((x - ox) / res)
            if 0 <= i < n_rows and 0 <= j < n_cols and not obstacle[i, j]:
                obstacle[i, j] = True
                added += 1
                stamp(inflated, i, j, disk)
        col_range[k] = hit if hit < math.inf else seen
    return added


@jit("void(b1[:, ::1], i8, i8, i8[:, ::1])")
def stamp(mask: Mask, i: int, j: int, disk: I64) -> None:
    """Set ``mask`` at cell ``(i, j)`` plus each ``disk`` offset, skipping cells outside the grid."""
    n_rows, n_cols = mask.shape
    for d in range(disk.shape[0]):
        ii = i + disk[d, 0]
        jj = j + disk[d, 1]
        if 0 <= ii < n_rows and 0 <= jj < n_cols:
            mask[ii, jj] = True


@jit("void(f8[::1], f8[::1], f8[::1], f8[::1], b1[:, ::1])")
def cast_rays(origin: F64, angles: F64, ranges: F64, grid: F64, explored: Mask) -> None:
    """Mark the cells along 2-D rays from ``origin`` = (x, y) at world ``angles`` out to ``ranges`` (metres).

    Rays are sampled every half cell and always include their end point, so the cell of an obstacle hit is
    marked too. ``grid`` = (origin x, origin y, resolution).
    """
    ox, oy, res = grid[0], grid[1], grid[2]
    n_rows, n_cols = explored.shape
    step = 0.5 * res
    for k in range(angles.shape[0]):
        r = ranges[k]
        if not r > 0.0:
            continue
        ca, sa = math.cos(angles[k]), math.sin(angles[k])
        n = math.ceil(r / step)
        for m in range(n + 1):
            t = min(m * step, r)
            i = math.floor((origin[1] + sa * t - oy) / res)
            j = math.floor((origin[0] + ca * t - ox) / res)
            if 0 <= i < n_rows and 0 <= j < n_cols:
                explored[i, j] = True


@jit("i8(b1[:, ::1], i8[:, ::1], i8[::1])")
def pocket_size(passable: Mask, cells: I64, window: I64) -> int:
    """Count the ``passable`` cells 4-connected to the 4-neighbours of ``cells`` inside ``window``.

    ``window`` = (row0, row1, col0, col1), half-open. The flood starts from every passable 4-neighbour of a
    member of ``cells`` (an (N, 2) array of rows and columns) that lies in the window: one :func:`_fill_runs` per
    seed not yet reached, whose components together are the pocket.
    """
    r0, r1, c0, c1 = window[0], window[1], window[2], window[3]
    inside = passable[r0:r1, c0:c1]
    h, w = inside.shape
    visited = np.zeros((h, w), dtype=np.bool_)
    stack = np.empty(h + w + 16, dtype=np.int64)
    size = 0
    for n in range(cells.shape[0]):
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            i, j = cells[n, 0] + di - r0, cells[n, 1] + dj - c0
            if 0 <= i < h and 0 <= j < w and inside[i, j] and not visited[i, j]:
                filled, stack = _fill_runs(inside, visited, i, j, False, stack)
                size += filled
    return size


@jit("i8[::1](b1[:, ::1], i8[:, ::1], i8[::1], i8)")
def pocket_sizes(passable: Mask, cells: I64, starts: I64, margin: int) -> I64:
    """:func:`pocket_size` of every group ``cells[starts[k]:starts[k + 1]]``, each in its bounding box grown by
    ``margin`` cells and clipped to ``passable`` (one call for all the frontiers of a step)."""
    rows, cols = passable.shape
    sizes = np.zeros(starts.shape[0] - 1, dtype=np.int64)
    window = np.empty(4, dtype=np.int64)
    for k in range(sizes.shape[0]):
        group = cells[starts[k] : starts[k + 1]]
        window[0] = max(group[:, 0].min() - margin, 0)
        window[1] = min(group[:, 0].max() + margin + 1, rows)
        window[2] = max(group[:, 1].min() - margin, 0)
        window[3] = min(group[:, 1].max() + margin + 1, cols)
        sizes[k] = pocket_size(passable, group, window)
    return sizes


@jit()
def _flood(mask: Mask, visited: Mask, i: int, j: int, eight: bool, queue: I64) -> int:
    """Mark in ``visited`` the 4- or 8-connected component of ``mask`` holding the set, unvisited cell ``(i, j)``,
    breadth-first; its cells' flat indices end up in ``queue[:n]`` (one slot per cell), and ``n`` is returned."""
    rows, cols = mask.shape
    visited[i, j] = True
    queue[0] = i * cols + j
    head, tail = 0, 1
    while head < tail:
        ci, cj = queue[head] // cols, queue[head] % cols
        head += 1
        for di in range(-1, 2):
            for dj in range(-1, 2):
                if (di == 0 and dj == 0) or (not eight and di != 0 and dj != 0):
                    continue
                ii, jj = ci + di, cj + dj
                if 0 <= ii < rows and 0 <= jj < cols and mask[ii, jj] and not visited[ii, jj]:
                    visited[ii, jj] = True
                    queue[tail] = ii * cols + jj
                    tail += 1
    return tail


@jit()
def _fill_runs(mask: Mask, visited: Mask, i: int, j: int, eight: bool, stack: I64) -> tuple[int, I64]:
    """Mark in ``visited`` the 4- or 8-connected component of ``mask`` holding the set, unvisited cell ``(i, j)``,
    a whole row run at a time (scan-line fill): the number of cells marked and the (possibly grown) seed stack.

    A popped seed is widened to its maximal run of unvisited ``mask`` cells in its row; the rows above and below are
    scanned under that run (one cell wider on each side with 8-connectivity) and the first cell of each unvisited
    ``mask`` run there is pushed. Marks exactly the cells :func:`_flood` marks, reading the rows sequentially instead
    of queueing every cell.
    """
    rows, cols = mask.shape
    stack[0] = i * cols + j
    top = 1
    count = 0
    while top > 0:
        top -= 1
        y, x = stack[top] // cols, stack[top] % cols
        if visited[y, x]:
            continue
        left, right = x, x
        while left > 0 and mask[y, left - 1] and not visited[y, left - 1]:
            left -= 1
        while right < cols - 1 and mask[y, right + 1] and not visited[y, right + 1]:
            right += 1
        visited[y, left : right + 1] = True
        count += right - left + 1
        lo, hi = (max(left - 1, 0), min(right + 1, cols - 1)) if eight else (left, right)
        for ny in (y - 1, y + 1):
            if ny < 0 or ny >= rows:
                continue
            in_run = False
            for q in range(lo, hi + 1):
                if not mask[ny, q] or visited[ny, q]:
                    in_run = False
                elif not in_run:
                    in_run = True
                    if top == stack.size:
                        grown = np.empty(2 * stack.size, dtype=np.int64)
                        grown[:top] = stack
                        stack = grown
                    stack[top] = ny * cols + q
                    top += 1
    return count, stack


@jit("b1[:, ::1](b1[:, ::1], i8, i8, b1)")
def flood_fill(mask: Mask, i: int, j: int, eight: bool) -> Mask:
    """The 4- or 8-connected component of ``mask`` holding cell ``(i, j)``, which must be set.

    Visits only the component (a row run at a time), so it costs what the component costs, not a labelling of the
    array.
    """
    visited = np.zeros(mask.shape, dtype=np.bool_)
    _fill_runs(mask, visited, i, j, eight, np.empty(sum(mask.shape) + 16, dtype=np.int64))
    return visited


@jit("Tuple((i8[:, ::1], i8[::1]))(b1[:, ::1])")
def raster_components(mask: Mask) -> tuple[I64, I64]:
    """The 8-connected components of ``mask``, numbered in raster order of their first cell (as
    ``scipy.ndimage.label`` numbers them): every set cell as ``(row, col)`` grouped by component, each group in
    raster order, and the ``count + 1`` offsets where the groups start and the last ends.

    Only the set cells are visited after one scan for them (frontier cells are a few hundred of a box of 10^5):
    each unvisited one in raster order starts the next component, whose flooded cells are sorted into raster order.
    """
    cols = mask.shape[1]
    flat = np.flatnonzero(mask)
    visited = np.zeros(mask.shape, dtype=np.bool_)
    queue = np.empty(flat.size, dtype=np.int64)
    cells = np.empty((flat.size, 2), dtype=np.int64)
    starts = np.zeros(flat.size + 1, dtype=np.int64)
    count = 0
    for f in flat:
        i, j = f // cols, f % cols
        if visited[i, j]:
            continue
        n = _flood(mask, visited, i, j, True, queue)
        group = np.sort(queue[:n])
        first = starts[count]
        for q in range(n):
            cells[first + q, 0] = group[q] // cols
            cells[first + q, 1] = group[q] % cols
        count += 1
        starts[count] = first + n
    return cells, starts[: count + 1].copy()
