"""Habitat-exact metrics and the paper's revisit count, against hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from drivenav import metrics


def test_success_needs_stop_and_distance() -> None:
    assert metrics.success(True, 0.2499, 0.25)
    assert not metrics.success(True, 0.25, 0.25)  # habitat-lab's Success: distance_to_target < success_distance
    assert not metrics.success(True, 0.2501, 0.25)
    assert not metrics.success(False, 0.0, 0.25)


def test_spl_is_shortest_over_taken_path() -> None:
    assert metrics.spl(True, 4.0, 5.0) == pytest.approx(0.8)
    assert metrics.spl(True, 4.0, 3.5) == pytest.approx(1.0)  # stopping early inside the success radius
    assert metrics.spl(False, 4.0, 4.0) == 0.0


@given(st.floats(0.0, 50.0), st.floats(0.0, 100.0), st.booleans())
def test_spl_bounded(d0: float, path: float, ok: bool) -> None:
    value = metrics.spl(ok, d0, path)
    assert 0.0 <= value <= 1.0
    if not ok:
        assert value == 0.0


def test_path_length_ignores_turns() -> None:
    positions = np.array([[0.0, 0.0], [0.0, 0.0], [0.25, 0.0], [0.25, 0.0], [0.25, 0.25]])
    assert metrics.path_length(positions) == pytest.approx(0.5)


def _line(x0: float, x1: float, y: float, step: float = 0.25) -> np.ndarray:
    n = round(abs(x1 - x0) / step)
    xs = np.linspace(x0, x1, n + 1)
    return np.stack([xs, np.full_like(xs, y)], axis=1)


def test_going_back_over_old_ground_is_a_revisit() -> None:
    out = _line(0.0, 8.0, 0.0)  # segment 0: 8 m east
    back = _line(8.0, 0.0, 0.3)[1:]  # segment 1: 8 m west, 0.3 m from the old path
    positions = np.concatenate([out, back])
    assert metrics.count_revisits(positions, [0, len(out) - 1]) == 1


def test_short_overlap_is_not_a_revisit() -> None:
    out = _line(0.0, 8.0, 0.0)
    back = _line(8.0, 4.0, 0.3)[1:]  # only 4 m back over old ground
    positions = np.concatenate([out, back])
    assert metrics.count_revisits(positions, [0, len(out) - 1]) == 0


def test_parallel_path_beyond_radius_is_not_a_revisit() -> None:
    out = _line(0.0, 8.0, 0.0)
    back = _line(8.0, 0.0, 0.6)[1:]  # 0.6 m away: outside 0.5 m
    positions = np.concatenate([out, back])
    assert metrics.count_revisits(positions, [0, len(out) - 1]) == 0


def test_one_segment_never_revisits() -> None:
    out = _line(0.0, 8.0, 0.0)
    back = _line(8.0, 0.0, 0.0)[1:]
    assert metrics.count_revisits(np.concatenate([out, back]), [0]) == 0
