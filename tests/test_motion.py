"""Forward steps, collisions, sliding and turns on hand-made navigable grids."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivenav.envs.embedded.motion import apply_action, forward_step, is_navigable, turn
from drivenav.grid import GridSpec
from drivenav.types import Action, Pose, SimConfig

RES = 0.05
GRID = GridSpec(RES, (0.0, 0.0), (80, 80))  # 4 m x 4 m


def open_square() -> np.ndarray:
    """Navigable where the agent centre is at least 0.2 m from the square's 4 m border."""
    nav = np.zeros(GRID.shape, bool)
    nav[4:-4, 4:-4] = True  # x, y in [0.2, 3.8)
    return nav


def test_free_step_is_exact() -> None:
    x, y, collided = forward_step(open_square(), GRID, 1.0, 1.0, 0.0, 0.25)
    assert (x, y, collided) == (pytest.approx(1.25), pytest.approx(1.0), False)


def test_step_into_wall_collides_and_stays_navigable() -> None:
    nav = open_square()
    x, y, collided = forward_step(nav, GRID, 3.7, 2.0, 0.0, 0.25)  # free up to x < 3.8
    assert collided
    assert is_navigable(nav, GRID, x, y)
    assert 3.75 <= x < 3.8 and y == pytest.approx(2.0)


def test_cannot_cross_a_one_cell_barrier() -> None:
    nav = open_square()
    nav[:, 40] = False  # a thin barrier at x in [2.0, 2.05)
    x, _, collided = forward_step(nav, GRID, 1.9, 2.0, 0.0, 0.25)
    assert collided and x < 2.0
    # Diagonal approach: still stopped (sliding is along y only, parallel to the barrier).
    x, y, collided = forward_step(nav, GRID, 1.95, 2.0, math.radians(30.0), 0.25)
    assert collided and x < 2.0 and y > 2.0


def test_slides_along_wall_at_45_degrees() -> None:
    nav = open_square()
    x, y, collided = forward_step(nav, GRID, 1.0, 3.7, math.pi / 4, 0.25)  # wall ahead-left at y = 3.8
    assert collided
    assert is_navigable(nav, GRID, x, y)
    # Full step would give dx = dy = 0.177; sliding keeps the whole x progress along the wall.
    assert x - 1.0 == pytest.approx(0.25 / math.sqrt(2.0), abs=1e-9)
    assert 3.75 <= y < 3.8


def test_blocked_corner_stops() -> None:
    nav = open_square()
    x, y, collided = forward_step(nav, GRID, 3.75, 3.75, math.pi / 4, 0.25)
    assert collided and is_navigable(nav, GRID, x, y)
    assert x < 3.8 and y < 3.8


def test_non_navigable_start_does_not_move() -> None:
    assert forward_step(open_square(), GRID, 0.1, 0.1, 0.0, 0.25) == (0.1, 0.1, True)


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(0.2, 3.79),
    y=st.floats(0.2, 3.79),
    yaw=st.floats(-math.pi, math.pi),
    distance=st.floats(0.0, 0.5),
    hole=st.tuples(st.integers(0, 79), st.integers(0, 79), st.integers(1, 12)),
)
def test_step_invariants(x: float, y: float, yaw: float, distance: float, hole: tuple[int, int, int]) -> None:
    nav = open_square()
    r, c, size = hole
    nav[r : r + size, c : c + size] = False  # an obstacle somewhere
    if not is_navigable(nav, GRID, x, y):
        return
    nx, ny, collided = forward_step(nav, GRID, x, y, yaw, distance)
    assert is_navigable(nav, GRID, nx, ny)
    moved = math.hypot(nx - x, ny - y)
    assert moved <= distance + 1e-9
    if not collided:
        assert nx == pytest.approx(x + distance * math.cos(yaw), abs=1e-9)
        assert ny == pytest.approx(y + distance * math.sin(yaw), abs=1e-9)
    # Never moves backwards relative to the heading.
    assert (nx - x) * math.cos(yaw) + (ny - y) * math.sin(yaw) >= -1e-9


def test_turns_are_30_degrees_left_ccw() -> None:
    step = math.radians(30.0)
    assert turn(0.0, Action.TURN_LEFT, step) == pytest.approx(step)
    assert turn(0.0, Action.TURN_RIGHT, step) == pytest.approx(-step)
    assert turn(math.pi - 0.1, Action.TURN_LEFT, step) == pytest.approx(-math.pi - 0.1 + step)
    assert turn(1.0, Action.STOP, step) == 1.0


def test_apply_action() -> None:
    cfg = SimConfig()
    nav = open_square()
    pose, collided = apply_action(nav, GRID, Pose(1.0, 1.0, math.pi / 2), Action.MOVE_FORWARD, cfg)
    assert not collided and (pose.x, pose.y) == (pytest.approx(1.0), pytest.approx(1.25))
    pose, collided = apply_action(nav, GRID, Pose(1.0, 1.0, 0.0), Action.STOP, cfg)
    assert pose == Pose(1.0, 1.0, 0.0) and not collided
    pose, _ = apply_action(nav, GRID, Pose(1.0, 1.0, 0.0), Action.TURN_LEFT, cfg)
    assert pose.yaw == pytest.approx(math.radians(30.0)) and (pose.x, pose.y) == (1.0, 1.0)
