"""The numba distance transforms and the bucketed FMM against scipy / scikit-fmm and closed forms."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import skfmm
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy import ndimage

from drivenav.directions.edt import edt, feature_transform, squared_edt
from drivenav.directions.fmm import travel_time

masks = arrays(np.bool_, st.tuples(st.integers(1, 25), st.integers(1, 25)), elements=st.booleans())


@settings(max_examples=60, deadline=None)
@given(masks)
def test_squared_edt_matches_scipy(feature: np.ndarray) -> None:
    got = squared_edt(feature)
    if not feature.any():
        assert np.isinf(got).all()
        return
    want = ndimage.distance_transform_edt(~feature) ** 2
    np.testing.assert_allclose(got, want, atol=1e-9)


sparse_masks = st.integers(0, 2**32 - 1).flatmap(
    lambda seed: st.just(np.random.default_rng(seed).random((1 + seed % 97, 1 + seed // 97 % 89)) < (seed % 7) / 60.0)
)


@settings(max_examples=80, deadline=None)
@given(st.one_of(masks, sparse_masks))
def test_edt_is_scipys_distance_bit_for_bit_and_the_squares_are_the_feature_transforms(feature: np.ndarray) -> None:
    """The one-array transform (scene loading, the skeleton's distances) gives exactly the numbers of scipy and of
    the feature transform, on small masks and on larger sparse ones (long empty column runs, empty rows)."""
    got = edt(feature)
    np.testing.assert_array_equal(squared_edt(feature), feature_transform(feature)[0])
    if not feature.any():
        assert np.isinf(got).all()
        return
    np.testing.assert_array_equal(got, ndimage.distance_transform_edt(~feature))


@settings(max_examples=60, deadline=None)
@given(masks)
def test_feature_transform_points_at_a_nearest_feature(feature: np.ndarray) -> None:
    sq, frow, fcol = feature_transform(feature)
    if not feature.any():
        assert (frow == -1).all() and (fcol == -1).all()
        return
    assert feature[frow, fcol].all()
    rows, cols = np.indices(feature.shape)
    np.testing.assert_array_equal((rows - frow) ** 2 + (cols - fcol) ** 2, sq)


def _wavy_speed(n: int) -> np.ndarray:
    rows, cols = np.indices((n, n))
    return 1.0 + 0.5 * np.sin(cols / 5.0) * np.cos(rows / 7.0)


def test_fmm_reproduces_scikit_fmm_first_order_with_obstacles() -> None:
    """Seeded with scikit-fmm's own initial band, the solutions agree to round-off: same first-order scheme."""
    n, h, c = 61, 0.1, 30
    speed = _wavy_speed(n)
    blocked = np.zeros((n, n), np.bool_)
    blocked[20:23, 10:50] = True
    blocked[35:50, 40:43] = True
    phi = np.ones((n, n))
    phi[c, c] = -1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = skfmm.travel_time(np.ma.MaskedArray(phi, blocked), speed, dx=h, order=1)
    ref_t = np.abs(ref.filled(np.inf))
    seeds = np.array([[c, c], [c - 1, c], [c + 1, c], [c, c - 1], [c, c + 1]])
    got = travel_time(np.where(blocked, 0.0, speed), h, seeds, ref_t[seeds[:, 0], seeds[:, 1]])
    free = ~blocked
    np.testing.assert_allclose(got[free], ref_t[free], rtol=1e-9)
    assert np.isinf(got[blocked]).all()


def test_fmm_point_source_in_uniform_speed_is_close_to_euclidean_distance() -> None:
    n, h, c = 101, 0.05, 50
    got = travel_time(np.full((n, n), 2.0), h, np.array([[c, c]]), np.zeros(1))
    rows, cols = np.indices((n, n))
    dist = np.hypot(rows - c, cols - c) * h / 2.0
    far = dist > 10 * h / 2.0
    rel = np.abs(got[far] - dist[far]) / dist[far]
    assert rel.max() < 0.07  # first-order FMM overestimates most along the diagonals
    axis = got[c, c + 1 :]  # exact along the grid axes
    np.testing.assert_allclose(axis, np.arange(1, n - c) * h / 2.0)


def test_fmm_walls_off_unreachable_cells_and_handles_a_traversable_border() -> None:
    speed = np.ones((30, 30))
    speed[:, 15] = 0.0  # a full-height wall
    got = travel_time(speed, 1.0, np.array([[0, 0]]), np.zeros(1))
    assert np.isinf(got[:, 15:]).all()
    assert got[0, 14] == pytest.approx(14.0)
    assert got[29, 0] == pytest.approx(29.0)


def test_fmm_detour_around_a_wall_is_longer_than_the_straight_line() -> None:
    speed = np.ones((41, 41))
    speed[5:41, 20] = 0.0  # wall with a gap at rows 0-4
    got = travel_time(speed, 1.0, np.array([[30, 10]]), np.zeros(1))
    # Geodesic over the wall cell's top corners (4.5, 19.5) and (4.5, 20.5); straight line would be 20.
    geodesic = 2 * np.hypot(25.5, 9.5) + 1.0
    assert geodesic <= got[30, 30] < 1.07 * geodesic


def test_early_termination_keeps_exact_values_up_to_the_targets() -> None:
    n = 81
    speed = _wavy_speed(n)
    speed[40, 10:70] = 0.0
    full = travel_time(speed, 0.05, np.array([[20, 40]]), np.zeros(1))
    labels = np.full((n, n), -1, np.int32)
    labels[10, 5:8] = 0
    labels[30, 60] = 1
    early = travel_time(speed, 0.05, np.array([[20, 40]]), np.zeros(1), target_label=labels, margin_cells=2.0)
    reached = np.isfinite(early)
    assert reached[10, 5:8].all() and reached[30, 60]
    np.testing.assert_allclose(early[reached], full[reached], rtol=1e-12)
    assert np.isinf(early[70, 40])  # beyond the wall: far past the last target, not marched
    horizon = max(full[10, 5:8].min(), full[30, 60]) + 2.0 * 0.05 / speed[speed > 0].min()
    assert reached[full < horizon - 0.05].all()


def test_unreachable_target_label_falls_back_to_a_full_solve() -> None:
    speed = np.ones((20, 20))
    speed[:, 10] = 0.0
    labels = np.full((20, 20), -1, np.int32)
    labels[5, 15] = 0  # behind the wall
    got = travel_time(speed, 1.0, np.array([[5, 2]]), np.zeros(1), target_label=labels, margin_cells=1.0)
    np.testing.assert_allclose(got[:, :10], travel_time(speed, 1.0, np.array([[5, 2]]), np.zeros(1))[:, :10])


def test_a_grid_too_large_for_the_32_bit_queue_is_refused() -> None:
    huge = np.broadcast_to(np.float64(1.0), (30_000, 20_000))  # 600 M cells, no memory behind them
    with pytest.raises(ValueError, match="too large"):
        travel_time(huge, 0.05, np.array([[1, 1]]), np.zeros(1))
