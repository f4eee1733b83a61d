"""Weighted Fast Marching with a bucketed ("untidy") priority queue and early termination (Sec. IV-A a).

Solves the first-order upwind (Godunov) discretisation of ``|grad T| F = 1`` on a grid with spacing ``h``
(Sethian, 1996) from seed cells with given arrival times. Cells with ``F <= 0`` are never entered and keep
``T = inf``.

Why not a binary heap: on the target machine a heap-ordered FMM over a 480 x 480 grid costs ~25-60 ms, almost
all of it in heap sift-downs. Here cells are kept in circular buckets of width ``delta`` (Yatziv et al., 2006,
"O(N) implementation of the fast marching algorithm") and processed bucket by bucket. Unlike the original untidy
queue, a cell whose value still decreases after it was processed is simply processed again (label correction,
as in the fast iterative method), so the result is the exact fixed point of the first-order scheme -- the
same numbers a heap-ordered FMM produces (tested against scikit-fmm) -- at roughly a quarter of the cost of the
heap version measured here (about 15 ms instead of 60 ms on an open 480 x 480 grid); re-processing is rare
(< 1 % of cells) because ``delta`` is below the smallest one-cell travel time.

Only the first-order scheme is offered: a second-order upwind update is not monotone, so under label
correction it is not guaranteed to settle. The first-order bias (arrival times up to ~7 % long along the grid
diagonals, exact along the axes) was judged acceptable for extracting bearings.

Early termination: cells may carry a target label ``>= 0``. Once a cell of every label has been processed,
marching goes on for a margin of travel time (so that backtracking from the targets sees settled neighbours) and
stops; cells whose time is not settled by then are set to ``inf``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from drivenav.jit import jit


@jit(error_model="numpy")
def _godunov_update(T: NDArray[np.float64], idx: int, cols: int, step: float) -> float:
    """First-order upwind solution at flat cell ``idx`` from its 4-neighbours' current values.

    ``step = h / F`` is the one-cell travel time there. The cell must not lie on the grid border.
    """
    a = min(float(T[idx - 1]), float(T[idx + 1]))
    b = min(float(T[idx - cols]), float(T[idx + cols]))
    lo = min(a, b)
    hi = max(a, b)
    single = lo + step
    if single <= hi:
        return single
    diff = hi - lo
    return 0.5 * (lo + hi + math.sqrt(2.0 * step * step - diff * diff))


_FREE, _TOP, _PENDING = 0, 1, 2


@jit(error_model="numpy")
def _push(
    head: NDArray[np.int32],
    links: NDArray[np.int32],
    cells: NDArray[np.int32],
    values: NDArray[np.float64],
    counters: NDArray[np.int64],
    slot: int,
    idx: int,
    value: float,
) -> None:
    """Queue cell ``idx`` with ``value`` in bucket ``slot``.

    Buckets are singly-linked LIFO lists: ``head[slot]`` is the first entry, ``links[e]`` the next entry and
    ``cells[e]`` the cell of entry ``e``. Popped entries are recycled through a free list.
    """
    e = counters[_FREE]
    if e >= 0:
        counters[_FREE] = links[e]
    else:
        e = counters[_TOP]
        if e == values.size:
            raise RuntimeError("FMM queue capacity exceeded")
        counters[_TOP] += 1
    links[e] = head[slot]
    cells[e] = idx
    values[e] = value
    head[slot] = e
    counters[_PENDING] += 1


@jit(error_model="numpy")
def _pop(
    head: NDArray[np.int32],
    links: NDArray[np.int32],
    counters: NDArray[np.int64],
    slot: int,
) -> int:
    """Remove the first entry of bucket ``slot``; returns the entry (its cell and queued value stay readable
    until the next push)."""
    e = head[slot]
    head[slot] = links[e]
    links[e] = counters[_FREE]
    counters[_FREE] = e
    counters[_PENDING] -= 1
    return int(e)


@jit(error_model="numpy")
def _one_cell_times(sp: NDArray[np.float64], h: float) -> tuple[NDArray[np.float64], float, float]:
    """Per cell, the one-cell travel time ``h / F`` (``-1`` where ``F <= 0``), and the largest and smallest
    positive speeds (``0`` and ``inf`` if there is none)."""
    cost = np.empty(sp.size)
    f_max = 0.0
    f_min = np.inf
    for k in range(sp.size):
        s = sp[k]
        if s > 0.0:
            f_max = max(f_max, s)
            f_min = min(f_min, s)
            cost[k] = h / s
        else:
            cost[k] = -1.0
    return cost, f_max, f_min


@jit("f8[:, ::1](f8[:, ::1], f8, i8[:, ::1], f8[::1], i4[:, ::1], i8, f8)", error_model="numpy")
def _march(
    speed: NDArray[np.float64],
    h: float,
    seeds: NDArray[np.int64],
    seed_times: NDArray[np.float64],
    target_label: NDArray[np.int32],
    n_labels: int,
    margin_cells: float,
) -> NDArray[np.float64]:
    rows, cols = speed.shape
    n_cells = rows * cols
    cost, f_max, f_min = _one_cell_times(speed.ravel(), h)
    T = np.full(n_cells, np.inf)
    if f_max == 0.0:
        return T.reshape(rows, cols)
    margin = margin_cells * h / f_min
    delta = h / (f_max * math.sqrt(2.0))  # the smallest possible one-cell increment
    spread = 2.0 * h / f_min + delta + (seed_times.max() - seed_times.min() if seed_times.size else 0.0)
    n_buckets = 1
    while n_buckets * delta < spread:  # queued values never span more than the ring
        n_buckets *= 2
    ring = n_buckets - 1  # n_buckets is a power of two: ``b & ring`` is ``b % n_buckets`` without a division
    capacity = 4 * n_cells + seeds.shape[0] + 16
    head = np.full(n_buckets, -1, np.int32)
    links = np.empty(capacity, np.int32)
    cells = np.empty(capacity, np.int32)
    values = np.empty(capacity, np.float64)
    counters = np.array([-1, 0, 0], np.int64)
    for k in range(seeds.shape[0]):
        idx = seeds[k, 0] * cols + seeds[k, 1]
        if cost[idx] >= 0.0 and seed_times[k] < T[idx]:
            T[idx] = seed_times[k]
            _push(head, links, cells, values, counters, int(seed_times[k] / delta) & ring, idx, seed_times[k])
    labels = target_label.ravel()
    reached = np.zeros(max(n_labels, 1), np.bool_)
    n_reached = 0
    stop_bucket = np.iinfo(np.int64).max
    current = np.iinfo(np.int64).max
    for k in range(seeds.shape[0]):
        current = min(current, int(T[seeds[k, 0] * cols + seeds[k, 1]] / delta))
    while counters[_PENDING] > 0 and current <= stop_bucket:
        slot = current & ring
        if head[slot] < 0:
            current += 1
            continue
        e = _pop(head, links, counters, slot)
        idx = cells[e]
        t_idx = T[idx]
        if values[e] > t_idx:
            continue  # stale: a smaller value for this cell was queued later
        label = labels[idx]
        if label >= 0 and not reached[label]:
            reached[label] = True
            n_reached += 1
            if n_reached == n_labels:
                stop_bucket = current + int(margin / delta) + 1
        for d in range(4):
            if d == 0:
                nb = idx - 1
            elif d == 1:
                nb = idx + 1
            elif d == 2:
                nb = idx - cols
            else:
                nb = idx + cols
            t_nb = T[nb]
            step = cost[nb]
            if t_nb <= t_idx or step < 0.0:
                continue  # blocked, or upwind of this cell: its update cannot use this cell's value
            candidate = _godunov_update(T, nb, cols, step)
            if candidate < t_nb * (1.0 - 1e-12):
                T[nb] = candidate
                bucket = max(int(candidate / delta), current)
                _push(head, links, cells, values, counters, bucket & ring, nb, candidate)
    if counters[_PENDING] > 0:
        limit = current * delta
        for idx in range(n_cells):
            if T[idx] >= limit:
                T[idx] = np.inf
    return T.reshape(rows, cols)


def travel_time(
    speed: NDArray[np.float64],
    h: float,
    seeds: NDArray[np.int64],
    seed_times: NDArray[np.float64],
    *,
    target_label: NDArray[np.int32] | None = None,
    margin_cells: float = 0.0,
) -> NDArray[np.float64]:
    """Arrival time ``T`` (metres at unit speed) from ``seeds`` ``(K, 2)`` ``(row, col)`` with ``seed_times``.

    ``target_label`` (same shape as ``speed``, ``-1`` = none, labels ``0..L-1``) enables early termination as
    described in the module docstring, the marching going on for ``margin_cells`` cells at the slowest speed
    (``margin_cells * h / min F`` of travel time) after the last label is reached; without it the whole reachable
    region is solved.
    """
    speed = np.asarray(speed, dtype=np.float64)
    if 4 * (speed.size + 2 * sum(speed.shape) + 4) + 16 >= 2**31:
        raise ValueError(f"a {speed.shape} grid is too large for the FMM's 32-bit queue")
    labels = np.full(speed.shape, -1, np.int32) if target_label is None else target_label
    n_labels = -1 if target_label is None else int(labels.max(initial=-1)) + 1
    seeds = np.asarray(seeds, dtype=np.int64).reshape(-1, 2)
    pad = bool(
        (speed[0, :] > 0).any() or (speed[-1, :] > 0).any() or (speed[:, 0] > 0).any() or (speed[:, -1] > 0).any()
    )
    if pad:  # the kernel needs a blocked border so that it can skip bounds checks
        speed = np.pad(speed, 1)
        labels = np.pad(labels, 1, constant_values=-1)
        seeds = seeds + 1
    T = _march(
        np.ascontiguousarray(speed),
        float(h),
        np.ascontiguousarray(seeds),
        np.asarray(seed_times, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(labels, dtype=np.int32),
        n_labels,
        float(margin_cells),
    )
    return np.asarray(T[1:-1, 1:-1] if pad else T, dtype=np.float64)
