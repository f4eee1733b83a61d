"""Pixel counts of instance-id images: the one-pass counts equal numpy's."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.typing import NDArray

from drivenav.instances import MAX_TABLE_ID, count_pixels_of, instance_areas

ids = st.one_of(st.integers(0, 9), st.integers(-3, 3), st.integers(MAX_TABLE_ID - 1, MAX_TABLE_ID + 2))


@settings(max_examples=120, deadline=None)
@given(
    semantic=arrays(np.int32, st.tuples(st.integers(0, 12), st.integers(1, 12)), elements=ids),
    wanted=arrays(np.int64, st.integers(0, 4), elements=ids),
)
def test_count_pixels_of_is_isin_counted(semantic: NDArray[np.int32], wanted: NDArray[np.int64]) -> None:
    assert count_pixels_of(semantic, wanted) == int(np.count_nonzero(np.isin(semantic, wanted)))


def test_count_pixels_of_a_frame_view() -> None:
    """A non-contiguous view (a crop of a frame) is counted like its copy."""
    frame = np.arange(48, dtype=np.int32).reshape(6, 8) % 5
    view = frame[1:5, ::2]
    assert count_pixels_of(view, np.array([1, 3])) == int(np.isin(view, [1, 3]).sum())


def test_every_integer_dtype_of_an_id_image_is_counted() -> None:
    """Worlds send int32, uint16, uint32, int64, ... id images: each counts as numpy counts it (the compiled counters
    take six dtypes; others go as int64)."""
    base = np.array([[0, 3, 3, 7], [7, 7, 0, 120]])
    for dtype in (np.int8, np.uint8, np.int16, np.uint16, np.int32, np.uint32, np.int64, np.uint64):
        semantic = base.astype(dtype)
        assert instance_areas(semantic) == {3: 2, 7: 3, 120: 1}, dtype
        assert count_pixels_of(semantic, np.array([7, 120])) == 4, dtype
