"""Speed field F = F_obs * F_vor (Eqs. 1-3), the medial skeleton, traversability and cropping."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.directions.edt import feature_transform
from drivenav.directions.speed import (
    build_speed_field,
    crop_window,
    medial_skeleton,
    speed_from_distances,
    traversable_mask,
    weighted_speed,
)
from drivenav.grid import GridSpec
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import SpeedFieldConfig

CFG = SpeedFieldConfig()


def test_speed_formula_hand_values() -> None:
    got = speed_from_distances(np.array([0.8, 0.0, np.inf]), np.array([0.0, 0.5, np.inf]), CFG)
    expected = [
        (1 - 0.65 * math.exp(-1.0)) * 4.0,
        0.35 * (1 + 3.0 * math.exp(-1.0)),
        1.0,
    ]
    np.testing.assert_allclose(got, expected)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.sampled_from([0.025, 0.05, 0.1]))
def test_lookup_table_speed_equals_the_formula(seed: int, res: float) -> None:
    rng = np.random.default_rng(seed)
    sq_obs = rng.integers(0, 90_000, (20, 20)).astype(np.float64)
    sq_vor = rng.integers(0, 90_000, (20, 20)).astype(np.float64)
    sq_obs[0, 0] = np.inf
    trav = rng.random((20, 20)) < 0.7
    got = weighted_speed(trav, sq_obs, sq_vor, CFG, res)
    want = np.where(trav, speed_from_distances(np.sqrt(sq_obs) * res, np.sqrt(sq_vor) * res, CFG), 0.0)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-5)


def _skeleton_of(obstacle: np.ndarray, region: np.ndarray) -> np.ndarray:
    sq, frow, fcol = feature_transform(obstacle)
    return medial_skeleton(region, sq, frow, fcol)


def test_skeleton_of_an_odd_width_corridor_is_its_centre_row() -> None:
    obstacle = np.zeros((41, 80), np.bool_)
    obstacle[9, :] = obstacle[31, :] = True  # free rows 10..30, centre row 20
    skeleton = _skeleton_of(obstacle, ~obstacle)
    rows = np.argwhere(skeleton[:, 5:75])[:, 0]
    assert set(rows.tolist()) == {20}
    assert skeleton[20, 5:75].all()


def test_skeleton_of_an_even_width_corridor_is_one_of_the_two_centre_rows() -> None:
    obstacle = np.zeros((40, 80), np.bool_)
    obstacle[9, :] = obstacle[30, :] = True  # free rows 10..29: centre between 19 and 20
    skeleton = _skeleton_of(obstacle, ~obstacle)
    cols = skeleton[:, 5:75]
    assert set(np.argwhere(cols)[:, 0].tolist()) <= {19, 20}
    assert cols.any(axis=0).all()


def test_skeleton_ignores_pixel_bumps_on_a_wall() -> None:
    obstacle = np.zeros((41, 80), np.bool_)
    obstacle[9, :] = obstacle[31, :] = True
    obstacle[10, 10:70:6] = True  # one-cell bumps
    skeleton = _skeleton_of(obstacle, ~obstacle)
    sq, _, _ = feature_transform(obstacle)
    assert np.sqrt(sq[skeleton]).min() >= 8.0  # nothing near the walls: no spurious branches
    assert skeleton[15:26, 5:75].any(axis=0).all()


def _snapshot(obstacle: np.ndarray, explored: np.ndarray, navigable: np.ndarray) -> MapSnapshot:
    return MapSnapshot(GridSpec(0.05, (1.0, -2.0), obstacle.shape), obstacle, explored, navigable)


def test_traversable_adds_frontier_cells_but_never_obstacles() -> None:
    obstacle = np.zeros((10, 10), np.bool_)
    obstacle[0, 0] = True
    navigable = np.zeros_like(obstacle)
    navigable[4:6, 2:5] = True
    cells = np.array([[4, 5], [5, 5], [0, 0], [20, 3]], dtype=np.int64)  # the last lies outside the grid
    frontier = Frontier(0, np.zeros((4, 2)), cells, (0.0, 0.0), 1.0)
    trav = traversable_mask(_snapshot(obstacle, navigable, navigable), [frontier])
    expected = navigable.copy()
    expected[4:6, 5] = True
    np.testing.assert_array_equal(trav, expected)


def test_crop_window_is_the_bounding_box_plus_margin_clipped_to_the_grid() -> None:
    grid = GridSpec(0.05, (1.0, -2.0), (50, 60))
    keep = np.zeros((50, 60), np.bool_)
    keep[10, 20] = keep[30, 58] = True
    w = crop_window(grid, keep, margin=2)
    assert (w.r0, w.r1, w.c0, w.c1) == (8, 33, 18, 60)
    assert w.grid.shape == (25, 42)
    assert w.grid.origin == pytest.approx((1.0 + 18 * 0.05, -2.0 + 8 * 0.05))
    empty = crop_window(grid, np.zeros((50, 60), np.bool_))
    assert (empty.r0, empty.r1, empty.c0, empty.c1) == (0, 50, 0, 60)


def _corridor_snapshot() -> MapSnapshot:
    obstacle = np.zeros((60, 100), np.bool_)
    obstacle[19, 10:90] = obstacle[41, 10:90] = True  # free rows 20..40, centre row 30
    explored = np.zeros_like(obstacle)
    explored[19:42, 10:90] = True
    navigable = explored & ~obstacle
    navigable[20:23, :] = navigable[38:41, :] = False  # inflation band
    return _snapshot(obstacle, explored, navigable)


def test_speed_field_peaks_on_the_skeleton_and_is_zero_off_traversable_cells() -> None:
    snapshot = _corridor_snapshot()
    field = build_speed_field(snapshot, [], CFG)
    w = field.window
    assert (w.r0, w.r1, w.c0, w.c1) == (17, 44, 8, 92)
    assert (field.speed[~field.traversable] == 0.0).all()
    centre = 30 - w.r0
    assert field.skeleton[centre, 10:70].all()
    d_obs = 11 * 0.05  # centre row is 11 cells from both walls
    want = (1 - 0.65 * math.exp(-d_obs / 0.8)) * 4.0
    np.testing.assert_allclose(field.speed[centre, 10:70], want)
    profile = field.speed[:, 40]
    assert int(np.argmax(profile)) == centre
    assert field.d_obs[centre, 40] == pytest.approx(d_obs)
    assert field.d_vor[centre + 3, 40] == pytest.approx(0.15)


def test_uniform_ablation_has_unit_speed_and_skips_the_transforms() -> None:
    field = build_speed_field(_corridor_snapshot(), [], SpeedFieldConfig(weighted=False))
    np.testing.assert_array_equal(field.speed, np.where(field.traversable, 1.0, 0.0))
    assert not field.skeleton.any()
    assert field.timings_ms["skeleton"] == 0.0


def test_without_obstacles_the_speed_is_one_everywhere() -> None:
    navigable = np.zeros((30, 30), np.bool_)
    navigable[5:25, 5:25] = True
    field = build_speed_field(_snapshot(np.zeros_like(navigable), navigable, navigable), [], CFG)
    assert not field.skeleton.any()
    np.testing.assert_allclose(field.speed[field.traversable], 1.0)
