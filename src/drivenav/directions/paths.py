"""Path recovery by gradient backtracking on the FMM arrival time (Sec. IV-A a, "gradient backtracking").

Positions inside the kernels are continuous ``(row, col)`` coordinates in which cell ``(i, j)`` has its centre
at ``(i, j)``. From a frontier's target cell the walker repeatedly steps ``STEP`` cells against the bilinearly
interpolated *upwind* gradient of ``T`` (per cell, the one-sided difference towards the smaller neighbour on
each axis -- the direction the Godunov scheme took the value from -- so ridges where two fronts meet do not
cancel out). A continuous step is accepted only if it stays in the current cell (at most ``MAX_SAME_CELL``
times in a row) or enters a traversable cell with a strictly smaller ``T`` whose crossing does not cut an
obstacle corner; otherwise the walker takes a discrete steepest-descent step to the 8-neighbour of least ``T``
(diagonals only between two traversable cells). Every cell change strictly lowers ``T``, so the walk always
terminates, and no segment of the polyline enters a non-traversable cell. The walk ends on reaching the source
cell or one of its 4-neighbours (the FMM seeds), then steps to the source centre.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drivenav.jit import jit

STEP = 1.0  # cells per continuous step (<= 1, so that a step crosses at most one boundary per axis)
MAX_SAME_CELL = 2  # continuous steps allowed without changing cell before a discrete step is forced


@jit(inline=True)
def _finite(T: NDArray[np.float64], i: int, j: int) -> bool:
    return bool(0 <= i < T.shape[0] and 0 <= j < T.shape[1] and T[i, j] < np.inf)


@jit(inline=True)
def _upwind_derivative(T: NDArray[np.float64], i: int, j: int, di: int, dj: int) -> float:
    """One-sided derivative of ``T`` at cell ``(i, j)`` along axis ``(di, dj)`` towards its smaller neighbour."""
    lo = float(T[i - di, j - dj]) if _finite(T, i - di, j - dj) else np.inf
    hi = float(T[i + di, j + dj]) if _finite(T, i + di, j + dj) else np.inf
    centre = float(T[i, j])
    if lo <= hi and lo < centre:
        return centre - lo
    if hi < lo and hi < centre:
        return hi - centre
    return 0.0


@jit(inline=True)
def _gradient(T: NDArray[np.float64], r: float, c: float) -> tuple[float, float]:
    """Bilinear interpolation of the per-cell upwind gradient over the finite-``T`` cells around ``(r, c)``."""
    i0 = math.floor(r)
    j0 = math.floor(c)
    fr = r - i0
    fc = c - j0
    gr = 0.0
    gc = 0.0
    for a in range(2):
        for b in range(2):
            i, j = i0 + a, j0 + b
            if not _finite(T, i, j):
                continue
            w = (fr if a else 1.0 - fr) * (fc if b else 1.0 - fc)
            gr += w * _upwind_derivative(T, i, j, 1, 0)
            gc += w * _upwind_derivative(T, i, j, 0, 1)
    return gr, gc


@jit(inline=True)
def _free(trav: NDArray[np.bool_], i: int, j: int) -> bool:
    return bool(0 <= i < trav.shape[0] and 0 <= j < trav.shape[1] and trav[i, j])


@jit(inline=True)
def _continuous_ok(T: NDArray[np.float64], trav: NDArray[np.bool_], ci: int, cj: int, ni: int, nj: int) -> bool:
    """Whether a short step from cell ``(ci, cj)`` into cell ``(ni, nj)`` is safe and makes progress."""
    if not _free(trav, ni, nj) or not T[ni, nj] < T[ci, cj]:
        return False
    return ni == ci or nj == cj or (_free(trav, ci, nj) and _free(trav, ni, cj))


@jit(inline=True)
def _steepest_neighbour(T: NDArray[np.float64], trav: NDArray[np.bool_], ci: int, cj: int) -> tuple[int, int]:
    """The 8-neighbour with least ``T`` below ``T[ci, cj]`` (no corner cutting); ``(-1, -1)`` if none."""
    best = T[ci, cj]
    bi, bj = -1, -1
    for di in range(-1, 2):
        for dj in range(-1, 2):
            ni, nj = ci + di, cj + dj
            if (di == 0 and dj == 0) or not _free(trav, ni, nj):
                continue
            if di != 0 and dj != 0 and not (_free(trav, ci, nj) and _free(trav, ni, cj)):
                continue
            if T[ni, nj] < best:
                best = T[ni, nj]
                bi, bj = ni, nj
    return bi, bj


@jit(inline=True)
def _append(buf: NDArray[np.float64], k: int, r: float, c: float) -> NDArray[np.float64]:
    if k == buf.shape[0]:
        grown = np.empty((2 * k, 2), np.float64)
        grown[:k] = buf
        buf = grown
    buf[k, 0] = r
    buf[k, 1] = c
    return buf


@jit()
def _walk(
    T: NDArray[np.float64],
    trav: NDArray[np.bool_],
    start_i: int,
    start_j: int,
    src_i: int,
    src_j: int,
    buf: NDArray[np.float64],
    k: int,
) -> tuple[NDArray[np.float64], int, bool]:
    """One walk from ``(start_i, start_j)`` to the source, its points appended to ``buf`` from row ``k``: the
    (possibly grown) buffer, the row after the walk's last point, and whether the walk reached the source."""
    r, c = float(start_i), float(start_j)
    ci, cj = start_i, start_j
    buf = _append(buf, k, r, c)
    k += 1
    same = 0
    while abs(ci - src_i) + abs(cj - src_j) > 1:
        moved = False
        if same < MAX_SAME_CELL:
            gr, gc = _gradient(T, r, c)
            norm = math.hypot(gr, gc)
            if norm > 1e-12:
                nr = r - STEP * gr / norm
                nc = c - STEP * gc / norm
                ni = math.floor(nr + 0.5)
                nj = math.floor(nc + 0.5)
                if (ni == ci and nj == cj) or _continuous_ok(T, trav, ci, cj, ni, nj):
                    same = same + 1 if (ni == ci and nj == cj) else 0
                    r, c, ci, cj = nr, nc, ni, nj
                    moved = True
        if not moved:
            bi, bj = _steepest_neighbour(T, trav, ci, cj)
            if bi < 0:
                return buf, k, False
            r, c, ci, cj = float(bi), float(bj), bi, bj
            same = 0
        buf = _append(buf, k, r, c)
        k += 1
    buf = _append(buf, k, float(src_i), float(src_j))
    return buf, k + 1, True


@jit("Tuple((f8[:, ::1], i8[::1], i8))(f8[:, ::1], b1[:, ::1], i8[:, ::1], i8, i8)")
def _backtrack_many_kernel(
    T: NDArray[np.float64], trav: NDArray[np.bool_], starts: NDArray[np.int64], src_i: int, src_j: int
) -> tuple[NDArray[np.float64], NDArray[np.int64], int]:
    """Every start's walk, concatenated: the points, the ``K + 1`` offsets of the walks, and the index of the
    first walk that stalled (``-1`` if none; the walks after it are not taken)."""
    offsets = np.zeros(starts.shape[0] + 1, np.int64)
    buf = np.empty((1024, 2), np.float64)
    n = 0
    for k in range(starts.shape[0]):
        buf, n, ok = _walk(T, trav, starts[k, 0], starts[k, 1], src_i, src_j, buf, n)
        if not ok:
            return buf[: offsets[k]].copy(), offsets, k
        offsets[k + 1] = n
    return buf[:n].copy(), offsets, -1


def backtrack_walks(
    T: NDArray[np.float64], traversable: NDArray[np.bool_], starts: NDArray[np.int64], source: tuple[int, int]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`backtrack` from each of the cells ``starts`` ``(K, 2)`` in one call (the frontiers of a step): every
    walk's points, concatenated, and the ``K + 1`` offsets where the walks start and the last ends."""
    starts = np.ascontiguousarray(starts, dtype=np.int64).reshape(-1, 2)
    bad = np.flatnonzero(~np.isfinite(T[starts[:, 0], starts[:, 1]]))
    if bad.size:
        raise ValueError(f"T is not finite at the start cell {tuple(int(v) for v in starts[bad[0]])}")
    points, offsets, stalled = _backtrack_many_kernel(
        np.ascontiguousarray(T, dtype=np.float64),
        np.ascontiguousarray(traversable, dtype=np.bool_),
        starts,
        int(source[0]),
        int(source[1]),
    )
    if stalled >= 0:
        start = tuple(int(v) for v in starts[stalled])
        raise RuntimeError(f"backtracking from {start} stalled before reaching {source}")
    return points, offsets


def backtrack(
    T: NDArray[np.float64], traversable: NDArray[np.bool_], start: tuple[int, int], source: tuple[int, int]
) -> NDArray[np.float64]:
    """Descend ``T`` from cell ``start`` to cell ``source``; returns continuous ``(row, col)`` points ``(N, 2)``
    from ``start`` to ``source`` (cell centres at integer coordinates).

    ``T`` must be finite at ``start``. Raises ``RuntimeError`` if no descending neighbour exists (only possible
    if ``T`` was not produced by a marching from ``source``).
    """
    points, _ = backtrack_walks(T, traversable, np.array([start], dtype=np.int64), source)
    return points
