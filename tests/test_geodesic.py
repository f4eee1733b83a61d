"""Geodesic distance fields on hand-built grids."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivenav.envs.embedded.geodesic import GeodesicField, largest_component
from drivenav.grid import GridSpec

RES = 0.05


def _open_grid(rows: int = 60, cols: int = 100) -> tuple[np.ndarray, GridSpec]:
    return np.ones((rows, cols), dtype=bool), GridSpec(RES, (0.0, 0.0), (rows, cols))


def test_straight_line_distance() -> None:
    nav, grid = _open_grid()
    field = GeodesicField(nav, grid, [(0.525, 1.525)])
    assert field.at(3.525, 1.525) == pytest.approx(3.0, abs=0.03)
    assert field.at(0.525, 1.525) == pytest.approx(0.0, abs=0.03)


def test_diagonal_distance_is_euclidean() -> None:
    nav, grid = _open_grid()
    field = GeodesicField(nav, grid, [(0.525, 0.525)])
    assert field.at(2.525, 2.525) == pytest.approx(2.0 * math.sqrt(2.0), rel=0.02)


def test_distance_bends_around_a_wall() -> None:
    nav, grid = _open_grid()
    nav[:45, 50] = False  # wall at x = 2.5 m from y = 0 to 2.25 m; gap above
    field = GeodesicField(nav, grid, [(1.525, 0.525)])
    straight = 2.0
    around = math.dist((1.525, 0.525), (2.525, 2.27)) + math.dist((2.525, 2.27), (3.525, 0.525))
    value = field.at(3.525, 0.525)
    assert value > straight + 1.0
    assert value == pytest.approx(around, rel=0.05)


def test_unreachable_is_infinite() -> None:
    nav, grid = _open_grid()
    nav[:, 50] = False
    field = GeodesicField(nav, grid, [(0.525, 0.525)])
    assert math.isinf(field.at(4.0, 1.0))
    assert math.isfinite(field.at(2.0, 1.0))


def test_no_goal_on_grid_gives_infinity() -> None:
    nav, grid = _open_grid()
    field = GeodesicField(nav, grid, [(-10.0, -10.0)])
    assert math.isinf(field.at(1.0, 1.0))


def test_largest_component() -> None:
    mask = np.zeros((10, 10), dtype=bool)
    mask[0:2, 0:2] = True
    mask[5:9, 5:9] = True
    big = largest_component(mask)
    assert big.sum() == 16 and big[6, 6] and not big[0, 0]


def test_largest_component_connects_through_sides_not_corners() -> None:
    mask = np.zeros((5, 5), dtype=bool)
    mask[0:2, 0:2] = True  # 4 cells
    mask[2:5, 2:5] = True  # 9 cells touching the first block only at a corner
    assert largest_component(mask).sum() == 9
    mask[2, 1] = True  # a side contact joins them
    assert largest_component(mask).sum() == 14
    assert not largest_component(np.zeros((3, 3), dtype=bool)).any()


def test_goals_filling_their_area_are_at_zero() -> None:
    """No free cell beside a goal leaves Fast Marching no front: goal cells are 0, the rest unreachable."""
    nav = np.zeros((5, 5), dtype=bool)
    nav[2, 2] = nav[0, 4] = True  # a one-cell room with the goal in it, and a cell elsewhere
    field = GeodesicField(nav, GridSpec(RES, (0.0, 0.0), (5, 5)), [(0.125, 0.125)])
    assert field.distances[2, 2] == 0.0 and field.at(0.125, 0.125) == 0.0
    assert np.isinf(np.delete(field.distances.ravel(), 12)).all()
