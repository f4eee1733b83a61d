"""Gradient backtracking never leaves traversable space; path/circle intersections are exact."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.directions.bearings import bearing_to, circle_crossing, normalize_angle
from drivenav.directions.fmm import travel_time
from drivenav.directions.paths import backtrack, backtrack_walks

N = 40


@st.composite
def obstacle_maps(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """A 40 x 40 map with random wall rectangles, a wavy speed and a free source cell."""
    trav = np.ones((N, N), np.bool_)
    for _ in range(draw(st.integers(0, 8))):
        r, c = draw(st.integers(0, N - 1)), draw(st.integers(0, N - 1))
        h, w = draw(st.integers(1, 20)), draw(st.integers(1, 4))
        if draw(st.booleans()):
            h, w = w, h
        trav[r : r + h, c : c + w] = False
    free = np.argwhere(trav)
    if free.size == 0:
        trav[0, 0] = True
        free = np.argwhere(trav)
    source = free[draw(st.integers(0, len(free) - 1))]
    rows, cols = np.indices((N, N))
    phase = draw(st.floats(0.0, 6.0))
    speed = np.where(trav, 1.0 + 0.8 * np.sin(cols / 4.0 + phase) * np.cos(rows / 6.0), 0.0)
    return trav, speed, (int(source[0]), int(source[1]))


def _cells_along(path: np.ndarray, samples: int = 24) -> np.ndarray:
    """The cells of points sampled densely along every segment (continuous coords: centres at integers)."""
    t = np.linspace(0.0, 1.0, samples)[None, :, None]
    pts = path[:-1, None, :] + t * (path[1:, None, :] - path[:-1, None, :])
    return np.floor(pts.reshape(-1, 2) + 0.5).astype(np.int64)


@settings(max_examples=40, deadline=None)
@given(obstacle_maps(), st.integers(0, 10_000))
def test_backtracked_paths_stay_in_traversable_cells_and_reach_the_source(
    scene: tuple[np.ndarray, np.ndarray, tuple[int, int]], pick: int
) -> None:
    trav, speed, source = scene
    T = travel_time(speed, 0.05, np.array([source]), np.zeros(1))
    reachable = np.argwhere(np.isfinite(T))
    for k in range(3):
        start = reachable[(pick * (k + 7)) % len(reachable)]
        path = backtrack(T, trav, (int(start[0]), int(start[1])), source)
        assert tuple(path[0]) == (start[0], start[1])
        assert tuple(path[-1]) == source
        cells = _cells_along(path)
        assert trav[cells[:, 0], cells[:, 1]].all()
        assert len(path) <= 4 * np.isfinite(T).sum() + 2


def test_backtracking_in_a_straight_corridor_runs_along_its_row() -> None:
    trav = np.zeros((9, 60), np.bool_)
    trav[3:6, 1:59] = True
    T = travel_time(np.where(trav, 1.0, 0.0), 1.0, np.array([[4, 5]]), np.zeros(1))
    path = backtrack(T, trav, (4, 55), (4, 5))
    np.testing.assert_allclose(path[:, 0], 4.0)
    assert np.all(np.diff(path[:, 1]) < 0)


def test_backtracking_turns_a_corner_without_cutting_it() -> None:
    trav = np.zeros((30, 30), np.bool_)
    trav[2:5, 2:28] = True  # horizontal leg
    trav[2:28, 23:26] = True  # vertical leg
    T = travel_time(np.where(trav, 1.0, 0.0), 1.0, np.array([[3, 3]]), np.zeros(1))
    path = backtrack(T, trav, (26, 24), (3, 3))
    cells = _cells_along(path, 50)
    assert trav[cells[:, 0], cells[:, 1]].all()
    assert tuple(path[-1]) == (3, 3)


def test_backtracking_rejects_an_unreached_start() -> None:
    T = np.full((5, 5), np.inf)
    T[2, 2] = 0.0
    with pytest.raises(ValueError, match="not finite"):
        backtrack(T, np.ones((5, 5), np.bool_), (0, 0), (2, 2))


def test_circle_crossing_on_a_straight_segment() -> None:
    assert circle_crossing(np.array([[0.0, 0.0], [1.0, 0.0]]), (0.0, 0.0), 0.8) == pytest.approx((0.8, 0.0))


def test_circle_crossing_is_exact_inside_a_segment_not_the_nearest_sample() -> None:
    path = np.array([[1.0, 1.0], [1.5, 1.5], [2.5, 1.5]])
    x, y = circle_crossing(path, (1.0, 1.0), 0.8)
    # |(0.5 + t, 0.5)| = 0.8  ->  t = sqrt(0.39) - 0.5
    assert (x, y) == pytest.approx((1.0 + 0.5 + math.sqrt(0.39) - 0.5, 1.5))
    assert math.hypot(x - 1.0, y - 1.0) == pytest.approx(0.8)


def test_circle_crossing_takes_the_first_exit_and_the_end_point_if_none() -> None:
    out_and_back = np.array([[0.0, 0.0], [0.0, 2.0], [0.0, 0.1], [3.0, 0.1]])
    assert circle_crossing(out_and_back, (0.0, 0.0), 0.8) == pytest.approx((0.0, 0.8))
    short = np.array([[0.0, 0.0], [0.3, 0.2], [0.1, 0.5]])
    assert circle_crossing(short, (0.0, 0.0), 0.8) == (0.1, 0.5)


def test_bearings_are_normalised_to_zero_two_pi() -> None:
    assert normalize_angle(-0.1) == pytest.approx(2 * math.pi - 0.1)
    assert normalize_angle(2 * math.pi) == 0.0
    assert normalize_angle(-1e-18) == 0.0
    assert bearing_to((1.0, 1.0), (1.0, 0.0)) == pytest.approx(1.5 * math.pi)
    assert bearing_to((0.0, 0.0), (-1.0, 0.0)) == pytest.approx(math.pi)


@settings(max_examples=30, deadline=None)
@given(obstacle_maps(), st.integers(0, 10_000), st.integers(0, 6))
def test_backtracking_many_starts_in_one_call_gives_each_walk_alone(
    scene: tuple[np.ndarray, np.ndarray, tuple[int, int]], pick: int, count: int
) -> None:
    trav, speed, source = scene
    T = travel_time(speed, 0.05, np.array([source]), np.zeros(1))
    reachable = np.argwhere(np.isfinite(T))
    starts = reachable[[(pick * (k + 3)) % len(reachable) for k in range(count)]].reshape(-1, 2)
    points, offsets = backtrack_walks(T, trav, starts, source)
    walks = [points[a:b] for a, b in itertools.pairwise(offsets)]
    assert len(walks) == len(starts)
    for start, walk in zip(starts, walks, strict=True):
        np.testing.assert_array_equal(walk, backtrack(T, trav, (int(start[0]), int(start[1])), source))


def test_backtracking_many_names_the_first_start_outside_the_solve() -> None:
    T = np.full((5, 5), np.inf)
    T[2, 2] = 0.0
    with pytest.raises(ValueError, match=r"\(0, 4\)"):
        backtrack_walks(T, np.ones((5, 5), np.bool_), np.array([[2, 2], [0, 4]]), (2, 2))
