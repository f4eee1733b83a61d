"""Pixel counts in instance-id images (a world's ``semantic`` observation), one pass over the pixels.

The embedded detector counts every instance of a frame and the worlds' ``target_seen`` measure counts the goal
instances' pixels, at every step; ``numpy.bincount`` first copies an ``int32`` image to ``intp`` and ``numpy.isin``
builds a lookup table per call, which cost two to four times the counting itself on a 640 x 480 frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from drivenav.jit import jit

MAX_TABLE_ID = 1 << 20  # larger (or negative) instance ids are counted by sorting, not with a table this long
ID_DTYPES = ("i4", "i8", "u1", "u2", "u4", "i2")  # id image dtypes the counters are compiled for; others go as int64


@jit(*(f"i8[::1]({t}[::1], i8)" for t in ID_DTYPES))
def _count_ids(flat: NDArray[np.integer], size: int) -> NDArray[np.int64]:
    counts = np.zeros(size, np.int64)
    for v in flat:
        counts[v] += 1
    return counts


@jit(*(f"i8({t}[::1], b1[::1])" for t in ID_DTYPES))
def _count_listed(flat: NDArray[np.integer], listed: NDArray[np.bool_]) -> int:
    n = 0
    top = listed.size
    for v in flat:
        if 0 <= v < top and listed[v]:
            n += 1
    return n


def instance_areas(semantic: NDArray[np.integer]) -> dict[int, int]:
    """Pixel count of every instance id present in ``semantic`` (id 0, nothing, left out), in increasing id order.

    Counted in one pass into a table when the ids are small non-negative integers, else by sorting.
    """
    flat = _flat_ids(semantic)
    top = int(flat.max()) if flat.size else -1
    if top >= 0 and int(flat.min()) >= 0 and top <= MAX_TABLE_ID:
        counts = _count_ids(flat, top + 1)
        ids = np.flatnonzero(counts)
        counts = counts[ids]
    else:
        ids, counts = np.unique(flat, return_counts=True)
    return {int(i): int(c) for i, c in zip(ids, counts, strict=True) if i != 0}


def count_pixels_of(semantic: NDArray[np.integer], ids: NDArray[np.integer]) -> int:
    """How many pixels of ``semantic`` hold one of ``ids`` (``np.isin`` counted, in one pass when the ids are
    small non-negative integers)."""
    wanted = np.asarray(ids).ravel()
    if wanted.size == 0 or semantic.size == 0:
        return 0
    if int(wanted.min()) < 0 or int(wanted.max()) > MAX_TABLE_ID:
        return int(np.count_nonzero(np.isin(semantic, wanted)))
    listed = np.zeros(int(wanted.max()) + 1, np.bool_)
    listed[wanted] = True
    return int(_count_listed(_flat_ids(semantic), listed))


def _flat_ids(semantic: NDArray[np.integer]) -> NDArray[np.integer]:
    """The image as one contiguous row of a dtype the counters are compiled for (others as int64: the same ids)."""
    flat = np.ascontiguousarray(semantic).ravel()
    return flat if flat.dtype.str[1:] in ID_DTYPES else flat.astype(np.int64)
