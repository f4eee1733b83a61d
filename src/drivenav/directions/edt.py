"""Exact Euclidean distance and feature transforms in linear time (Felzenszwalb & Huttenlocher, 2012).

The speed field of Sec. IV-A(a) needs two transforms per mapping step: the obstacle feature transform (``d_obs``,
and the nearest obstacles from which the medial skeleton is read) and the distance to the skeleton (``d_vor``).
``scipy.ndimage.distance_transform_edt`` costs ~10 ms each on a 480 x 480 grid, so this module provides a
single-threaded numba version, and :class:`IncrementalTransform` keeps one up to date across steps by redoing only
the columns and rows a change reaches. Distances are in cells; multiply by the resolution for metres. The embedded
world's scene loading (navigable grid, contact shadow, object placement) uses :func:`edt` for its memory: one and a
half grid-sized arrays where scipy needs about five.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from drivenav.jit import jit

SAME, LOWERED, REDO = 0, 1, 2  # what a row's column-pass values did: nothing; changed, none grew; some grew
MAX_LOWERED = 16  # changed columns up to which a LOWERED row is patched instead of redone


@jit("Tuple((i1[::1], b1[:, ::1]))(b1[:, ::1], i8[::1], f8[:, ::1], i4[:, ::1], i4[:, ::1])")
def _column_pass(
    feature: NDArray[np.bool_],
    columns: NDArray[np.int64],
    g: NDArray[np.float64],
    near: NDArray[np.int32],
    up: NDArray[np.int32],
) -> tuple[NDArray[np.int8], NDArray[np.bool_]]:
    """Redo the column pass (see :func:`_whole_column_pass`) of the columns ``columns`` in ``g`` and ``near``;
    ``up[i, k]`` is scratch for the nearest feature row at or above cell ``(i, columns[k])``.

    Returns each row's status (``SAME``, ``LOWERED`` or ``REDO``) and which of ``columns`` changed in each row
    (``changed[i, k]``)."""
    rows, cols = feature.shape
    big = np.int32(rows + cols + 1)
    for k in range(columns.size):
        up[0, k] = 0 if feature[0, columns[k]] else -big
    for i in range(1, rows):
        for k in range(columns.size):
            up[i, k] = i if feature[i, columns[k]] else up[i - 1, k]
    status = np.full(rows, SAME, np.int8)
    changed = np.zeros((rows, columns.size), np.bool_)
    below = np.full(columns.size, np.int32(2 * big), np.int32)
    for i in range(rows - 1, -1, -1):
        for k in range(columns.size):
            j = columns[k]
            if feature[i, j]:
                below[k] = i
            sq, nearest = _nearer(i, up[i, k], below[k], big)
            if sq != g[i, j] or nearest != near[i, j]:
                changed[i, k] = True
                status[i] = max(status[i], REDO if sq > g[i, j] else LOWERED)
            g[i, j] = sq
            near[i, j] = nearest
    return status, changed


@jit(inline=True)
def _nearer(i: int, above: int, below: int, big: int) -> tuple[float, int]:
    """The squared distance from row ``i`` to the nearer of the feature rows ``above`` and ``below`` (the one
    above on a tie) and that row; ``(inf, -1)`` when neither is within ``big`` rows (there is none)."""
    dist = i - above
    nearest = above
    if below - i < dist:
        nearest = below
        dist = below - i
    if dist >= big:
        return np.inf, -1
    return float(dist * dist), nearest


@jit("void(b1[:, ::1], f8[:, ::1], i4[:, ::1])")
def _whole_column_pass(feature: NDArray[np.bool_], g: NDArray[np.float64], near: NDArray[np.int32]) -> None:
    """Per column: the squared row distance to the nearest feature cell into ``g`` and that cell's row into ``near``
    (-1: none; ties go to the cell above). Row-major, so that each row's loop runs over contiguous cells (``near``
    holds the nearest feature row at or above a cell until the upward sweep replaces it)."""
    rows, cols = feature.shape
    big = np.int32(rows + cols + 1)
    for j in range(cols):
        near[0, j] = 0 if feature[0, j] else -big
    for i in range(1, rows):
        for j in range(cols):
            near[i, j] = i if feature[i, j] else near[i - 1, j]
    below = np.full(cols, 2 * big, np.int32)
    for i in range(rows - 1, -1, -1):
        for j in range(cols):
            if feature[i, j]:
                below[j] = i
            g[i, j], near[i, j] = _nearer(i, near[i, j], below[j], big)


@jit()
def _row_pass(
    g: NDArray[np.float64],
    out_sq: NDArray[np.float64],
    out_col: NDArray[np.int32],
    v: NDArray[np.int64],
    fv: NDArray[np.float64],
) -> None:
    """1-D squared distance transform of the row ``g`` into ``out_sq`` (and the nearest column into ``out_col``
    unless it is empty): lower envelope of the parabolas ``(q - v)^2 + g[v]``, built without divisions (all
    quantities are integers held in floats)."""
    cols = g.shape[0]
    columns = out_col.shape[0] > 0
    k = -1
    for q in range(cols):
        fq = g[q]
        if fq == np.inf:
            continue
        fq += q * q
        while k >= 1 and (fq - fv[k]) * (v[k] - v[k - 1]) <= (fv[k] - fv[k - 1]) * (q - v[k]):
            k -= 1
        k += 1
        v[k] = q
        fv[k] = fq
    if k < 0:
        out_sq[:] = np.inf
        if columns:
            out_col[:] = -1
        return
    m = 0
    for q in range(cols):
        while m < k and fv[m + 1] - fv[m] < 2.0 * q * (v[m + 1] - v[m]):
            m += 1
        d = q - v[m]
        out_sq[q] = fv[m] - v[m] * v[m] + d * d
        if columns:
            out_col[q] = v[m]


@jit("b1[::1](f8[:, ::1], i4[:, ::1], i1[::1], i8[::1], b1[:, ::1], f8[:, ::1], i4[:, ::1], i4[:, ::1])")
def _row_passes(
    g: NDArray[np.float64],
    near: NDArray[np.int32],
    status: NDArray[np.int8],
    columns: NDArray[np.int64],
    changed_at: NDArray[np.bool_],
    sq: NDArray[np.float64],
    frow: NDArray[np.int32],
    fcol: NDArray[np.int32],
) -> NDArray[np.bool_]:
    """The row pass of every row whose ``status`` is not ``SAME`` (see :func:`_column_pass`; ``REDO`` everywhere
    for a whole transform, with ``changed_at`` empty): squared distances into ``sq`` (which may be ``g`` itself: a
    row is read before it is written) and, unless ``fcol`` is empty, the nearest feature cell into ``frow``/``fcol``.
    With ``changed_at`` (not empty), the outputs are compared and the rows whose outputs changed are flagged in the
    result, and a ``LOWERED`` row with at most ``MAX_LOWERED`` changed columns is patched (:func:`_lower_row`)
    instead of redone."""
    rows, cols = g.shape
    compare = changed_at.size > 0
    features = fcol.size > 0
    row_sq = np.empty(cols, np.float64)
    row_col = np.empty(cols if features else 0, np.int32)
    v = np.empty(cols, np.int64)
    fv = np.empty(cols, np.float64)
    changed = np.zeros(rows, np.bool_)
    for i in range(rows):
        if status[i] == SAME:
            continue
        if status[i] == LOWERED and compare and changed_at[i].sum() <= MAX_LOWERED:
            changed[i] = _lower_row(g, near, columns, changed_at, sq, frow, fcol, i)
            continue
        if not compare:  # straight into the outputs (a copy of the row first: ``sq`` may be ``g``)
            row_sq[:] = g[i]
            _row_pass(row_sq, sq[i], fcol[i] if features else row_col, v, fv)
            if features:
                for q in range(cols):
                    c = fcol[i, q]
                    frow[i, q] = near[i, c] if c >= 0 else -1
            continue
        _row_pass(g[i], row_sq, row_col, v, fv)
        same = True
        for q in range(cols):
            if row_sq[q] != sq[i, q]:
                same = False
            sq[i, q] = row_sq[q]
        if features:
            for q in range(cols):
                c = row_col[q]
                r = near[i, c] if c >= 0 else -1
                if c != fcol[i, q] or r != frow[i, q]:
                    same = False
                fcol[i, q] = c
                frow[i, q] = r
        changed[i] = not same
    return changed


@jit()
def _lower_row(
    g: NDArray[np.float64],
    near: NDArray[np.int32],
    columns: NDArray[np.int64],
    changed_at: NDArray[np.bool_],
    sq: NDArray[np.float64],
    frow: NDArray[np.int32],
    fcol: NDArray[np.int32],
    i: int,
) -> bool:
    """Patch row ``i`` of a transform whose column-pass values ``g`` only fell (or kept their value with a new
    nearest row) in its flagged ``columns``; whether its outputs changed.

    The row pass is the lower envelope of the parabolas ``(q - c)^2 + g[c]``; a lowered parabola lies below the one
    it replaces, so the new envelope is the old one's minimum with the changed parabolas. Felzenszwalb-Huttenlocher
    gives a tie to the leftmost parabola, so a changed column takes a cell on a tie if it lies left of the cell's
    nearest column. Feature rows are then re-read through ``near``."""
    cols = g.shape[1]
    features = fcol.size > 0
    changed = False
    for k in range(columns.size):
        if not changed_at[i, k]:
            continue
        c = columns[k]
        gc = g[i, c]
        for q in range(cols):
            d = q - c
            value = gc + d * d
            if value < sq[i, q]:
                sq[i, q] = value
                changed = True
                if features:
                    fcol[i, q] = c
            elif features and value == sq[i, q] and c < fcol[i, q]:
                fcol[i, q] = c
                changed = True
    if features:
        for q in range(cols):
            c = fcol[i, q]
            r = near[i, c] if c >= 0 else -1
            if r != frow[i, q]:
                frow[i, q] = r
                changed = True
    return changed


@jit("UniTuple(b1[::1], 2)(b1[:, ::1], b1[:, ::1])")
def _sync(mask: NDArray[np.bool_], kept: NDArray[np.bool_]) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """A flag per row and one per column: ``mask`` differs from ``kept`` there; ``kept`` is brought up to date."""
    rows, cols = mask.shape
    row_changed = np.zeros(rows, np.bool_)
    col_changed = np.zeros(cols, np.bool_)
    for i in range(rows):
        for j in range(cols):
            if mask[i, j] != kept[i, j]:
                row_changed[i] = True
                col_changed[j] = True
                kept[i, j] = mask[i, j]
    return row_changed, col_changed


def changed_rows(mask: NDArray[np.bool_], kept: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """A flag per row: ``mask`` differs from ``kept`` (same shape) there; ``kept`` is brought up to date."""
    return np.asarray(_sync(_contiguous(mask), kept)[0])


def squared_edt(feature: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Squared Euclidean distance (cells^2) from every cell to the nearest ``True`` cell; ``inf`` if none.

    The row passes write back into the column pass's distances, so no second grid-sized distance array is made."""
    return _whole_transform(_contiguous(feature), None, False)[0]


def edt(feature: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Euclidean distance (cells) from every cell to the nearest ``True`` cell; ``inf`` everywhere if there is none.

    The same numbers as ``scipy.ndimage.distance_transform_edt(~feature)`` wherever ``feature`` has a cell (the
    square root of the same exact integer; for an empty ``feature`` scipy measures to a cell beyond the grid's
    corner), with one and a half grid-sized arrays (the distances and the column pass's feature rows) where scipy
    needs about five (feature indices, index grid, differences, squares): 17 MB instead of about 55 MB on a
    1477 x 980 floor plan.
    """
    sq = squared_edt(feature)
    return np.sqrt(sq, out=sq)


def feature_transform(
    feature: NDArray[np.bool_],
) -> tuple[NDArray[np.float64], NDArray[np.int32], NDArray[np.int32]]:
    """Squared distance plus the ``(row, col)`` of the nearest feature cell (``-1`` where there is none)."""
    kept = IncrementalTransform(feature, features=True)
    return kept.sq, kept.frow, kept.fcol


class IncrementalTransform:
    """The squared distance transform of a boolean grid (and, with ``features``, the nearest feature cell), kept
    up to date as the grid changes a little between calls (a depth frame adds obstacles in a few columns).

    Felzenszwalb-Huttenlocher is separable and each pass is exact per whole line: a column's pass depends on that
    column's cells only, a row's pass on that row's column-pass values only. :meth:`update` therefore redoes the
    column pass of the columns whose cells changed and the row pass of the rows whose column-pass values changed,
    and gives exactly the numbers, nearest cells and tie-breaks of a transform of the whole grid.
    """

    def __init__(self, feature: NDArray[np.bool_], features: bool) -> None:
        self._feature = np.array(feature, dtype=np.bool_, order="C")
        self.sq = np.empty(self._feature.shape, np.float64)
        self._g, self._near, self.frow, self.fcol = _whole_transform(self._feature, self.sq, features)

    @property
    def shape(self) -> tuple[int, int]:
        rows, cols = self._feature.shape
        return rows, cols

    def update(self, feature: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Bring the transform to ``feature`` (the shape given at construction); a flag per row: its outputs
        (``sq``, and ``frow``/``fcol`` with features) changed."""
        columns = np.flatnonzero(_sync(_contiguous(feature), self._feature)[1])
        if columns.size == 0:
            return np.zeros(self.shape[0], np.bool_)
        up = np.empty((self.shape[0], columns.size), np.int32)
        status, changed_at = _column_pass(self._feature, columns, self._g, self._near, up)
        changed = _row_passes(self._g, self._near, status, columns, changed_at, self.sq, self.frow, self.fcol)
        return np.asarray(changed)


def _whole_transform(
    feature: NDArray[np.bool_], sq: NDArray[np.float64] | None, features: bool
) -> tuple[NDArray[np.float64], NDArray[np.int32], NDArray[np.int32], NDArray[np.int32]]:
    """The column-pass distances ``g`` and rows ``near`` of ``feature``, and its row passes written into ``sq``
    (into ``g`` itself when None); then ``frow``/``fcol``, empty unless ``features``."""
    rows, cols = feature.shape
    g = np.empty((rows, cols), np.float64)
    near = np.empty((rows, cols), np.int32)
    _whole_column_pass(feature, g, near)
    shape = (rows, cols) if features else (0, 0)
    frow, fcol = np.empty(shape, np.int32), np.empty(shape, np.int32)
    none = np.empty(0, np.int64)
    redo = np.full(rows, REDO, np.int8)
    _row_passes(g, near, redo, none, np.empty((0, 0), np.bool_), g if sq is None else sq, frow, fcol)
    return g, near, frow, fcol


def _contiguous(feature: NDArray[np.bool_]) -> NDArray[np.bool_]:
    return np.ascontiguousarray(feature, dtype=np.bool_)
