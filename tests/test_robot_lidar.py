"""The field-of-view LiDAR occupancy (drivenav.robot.lidar, paper Sec. V-E) against hand-computed cells."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from drivenav.robot.lidar import LidarConfig, LidarOccupancy, fov_ranges
from drivenav.types import FREE_CELL, OCCUPIED_CELL, UNKNOWN_CELL, LocalOccupancy, Pose

ORIGIN = Pose(0.0, 0.0, 0.0)


def wall(x: float, y_from: float, y_to: float, z: float = 0.5) -> NDArray[np.float32]:
    """Points every centimetre along the base-frame segment ``x = const``, ``y in [y_from, y_to]``."""
    ys = np.arange(round((y_to - y_from) / 0.01) + 1) * 0.01 + y_from
    return np.stack([np.full_like(ys, x), ys, np.full_like(ys, z)], axis=1).astype(np.float32)


def point(x: float, y: float, z: float = 0.5) -> NDArray[np.float32]:
    return np.array([[x, y, z]], dtype=np.float32)


def cell(window: LocalOccupancy, x: float, y: float) -> int:
    """The state of the window cell holding the episode-frame point ``(x, y)``."""
    col = math.floor((x - window.origin[0]) / window.resolution)
    row = math.floor((y - window.origin[1]) / window.resolution)
    return int(window.cells[row, col])


def mapped(*scans: NDArray[np.float32], pose: Pose = ORIGIN, gimbal_yaw: float = 0.0) -> LocalOccupancy:
    grid = LidarOccupancy()
    for scan in scans:
        grid.update(scan, pose, gimbal_yaw)
    return grid.window(pose)


# ------------------------ config and bins


def test_config_defaults_follow_the_agent() -> None:
    config = LidarConfig()
    assert (config.min_height, config.max_height, config.hfov_deg) == (0.15, 0.88, 79.0)
    assert config.bins == 158  # 79 / 0.5


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"min_height": 1.0}, "max_height"),
        ({"hfov_deg": 0.0}, "hfov_deg"),
        ({"bin_deg": 0.0}, "bin_deg"),
        ({"max_range": -1.0}, "max_range"),
        ({"resolution": 0.0}, "resolution"),
        ({"window": 0.01}, "window"),
        ({"hit": -0.1}, "hit"),
        ({"miss": 0.1}, "miss"),
        ({"free_threshold": 0.1}, "free_threshold"),
        ({"occupied_threshold": -0.1}, "occupied_threshold"),
        ({"clamp_min": -0.2}, "clamp_min"),
        ({"clamp_max": 0.5}, "clamp_max"),
        ({"max_range": math.nan}, "max_range"),
    ],
)
def test_config_rejects_bad_values_naming_the_field(changes: dict[str, float], field: str) -> None:
    with pytest.raises(ValueError, match=f"LidarConfig.{field} "):
        LidarConfig(**changes)


def test_fov_ranges_bins_the_nearest_return_per_bearing() -> None:
    # Bins of 0.5 deg from -39.5 deg: bin 79 is [0, 0.5) deg, centre 0.25 deg. Two returns in it (ranges 2 and
    # 3), one at 10.2 deg (bin floor(49.7 / 0.5) = 99) 1.5 m away, one beyond max_range.
    at_10 = math.radians(10.2)
    points = np.array(
        [
            [2.0, 0.001, 0.5],
            [3.0, 0.001, 0.5],
            [1.5 * math.cos(at_10), 1.5 * math.sin(at_10), 0.5],
            [10.5, 0.001, 0.5],
        ]
    )
    bearings, ranges = fov_ranges(points, 0.0, LidarConfig())
    assert bearings.dtype == np.float64 and ranges.dtype == np.float64
    assert bearings.shape == ranges.shape == (158,)
    assert bearings[0] == pytest.approx(math.radians(-39.25))
    assert bearings[79] == pytest.approx(math.radians(0.25))
    assert ranges[79] == pytest.approx(2.0, abs=1e-5)
    assert ranges[99] == pytest.approx(1.5)
    assert np.isinf(np.delete(ranges, [79, 99])).all()  # no return: inf, not max_range


def test_fov_ranges_keeps_only_the_height_band_and_the_field_of_view() -> None:
    at_60 = math.radians(60.0)
    points = np.array(
        [
            [2.0, 0.001, 0.05],  # under the band
            [2.0, 0.001, 1.5],  # over the band
            [2.0 * math.cos(at_60), 2.0 * math.sin(at_60), 0.5],  # 60 deg: outside +-39.5
            [2.0, 0.001, 0.15],  # on the band's edges: kept
            [2.5, 0.001, 0.88],
        ]
    )
    _, ranges = fov_ranges(points, 0.0, LidarConfig())
    assert np.flatnonzero(np.isfinite(ranges)).tolist() == [79]
    assert ranges[79] == pytest.approx(2.0, abs=1e-5)


def test_fov_ranges_turns_with_the_gimbal() -> None:
    # Camera turned 60 deg left: the return at 60 deg is now at bearing 0 (bin 79) and the one straight ahead of
    # the base is at -60 deg, outside the field of view.
    at_60 = math.radians(60.0)
    points = np.array([[2.0 * math.cos(at_60 + 0.001), 2.0 * math.sin(at_60 + 0.001), 0.5], [3.0, 0.0, 0.5]])
    _, ranges = fov_ranges(points, at_60, LidarConfig())
    assert np.flatnonzero(np.isfinite(ranges)).tolist() == [79]
    assert ranges[79] == pytest.approx(2.0)


# ------------------------ occupancy grid


def test_window_is_centred_on_the_robot_and_aligned_to_the_resolution() -> None:
    # 10 m at 0.05 m: 200 cells; the robot's cell (col floor(1.23 / 0.05) = 24, row floor(-0.51 / 0.05) = -11)
    # sits at (100, 100).
    window = LidarOccupancy().window(Pose(1.23, -0.51, 0.3))
    assert window.cells.shape == (200, 200) and window.cells.dtype == np.int8
    assert window.origin == pytest.approx(((24 - 100) * 0.05, (-11 - 100) * 0.05))
    assert window.resolution == 0.05
    assert (window.cells == UNKNOWN_CELL).all()


def test_a_wall_ahead_is_occupied_and_the_space_before_it_free() -> None:
    # Wall face at x = 2.025 (the middle of the cells x in [2.00, 2.05)) for |y| <= 1 m.
    window = mapped(wall(2.025, -1.0, 1.0))
    for y in np.arange(-0.975, 0.976, 0.05):
        assert cell(window, 2.025, y) == OCCUPIED_CELL, y
    for x in (0.025, 0.525, 1.025, 1.525, 1.975):
        assert cell(window, x, 0.025) == FREE_CELL, x
    assert cell(window, 2.075, 0.025) == UNKNOWN_CELL  # behind the wall
    rows, cols = np.nonzero(window.cells == OCCUPIED_CELL)
    assert np.allclose(window.origin[0] + (cols + 0.5) * 0.05, 2.025)  # one column of cells ...
    assert np.abs(window.origin[1] + (rows + 0.5) * 0.05).max() < 1.05  # ... no longer than the wall


def test_bins_without_a_return_are_free_up_to_max_range_only_inside_the_field_of_view() -> None:
    # The wall spans bearings up to atan(1 / 2.025) = 26.3 deg; the ray of the bin centred on 35.25 deg has no
    # return and is cast free to max_range (10 m), not beyond.
    grid = LidarOccupancy(LidarConfig(window=24.0))
    grid.update(wall(2.025, -1.0, 1.0), ORIGIN)
    window = grid.window(ORIGIN)
    at_35, at_45 = math.radians(35.25), math.radians(45.0)
    for distance, state in [(4.0, FREE_CELL), (9.9, FREE_CELL), (10.5, UNKNOWN_CELL)]:
        assert cell(window, distance * math.cos(at_35), distance * math.sin(at_35)) == state, distance
    assert cell(window, 4.0 * math.cos(at_45), 4.0 * math.sin(at_45)) == UNKNOWN_CELL  # outside +-39.5 deg
    assert cell(window, -1.0, 0.0) == UNKNOWN_CELL  # behind the robot


def test_a_return_outside_the_field_of_view_is_ignored() -> None:
    at_60 = math.radians(60.0)
    x60, y60 = 2.0 * math.cos(at_60), 2.0 * math.sin(at_60)
    with_it = mapped(np.concatenate([wall(2.025, -1.0, 1.0), point(x60, y60)]))
    assert cell(with_it, x60, y60) == UNKNOWN_CELL
    assert np.array_equal(with_it.cells, mapped(wall(2.025, -1.0, 1.0)).cells)


def test_returns_outside_the_height_band_are_ignored() -> None:
    # The floor (z = 0.05) and the ceiling (z = 1.5) 1 m ahead: the ray to the wall crosses them as free space.
    scan = np.concatenate([wall(2.025, -1.0, 1.0), point(1.025, 0.025, 0.05), point(1.025, 0.025, 1.5)])
    window = mapped(scan)
    assert cell(window, 1.025, 0.025) == FREE_CELL


def test_the_gimbal_turns_the_field_of_view() -> None:
    # Camera turned 60 deg left: its field of view spans base bearings 20.5 to 99.5 deg. The return at 60 deg is
    # mapped; of the wall (base bearings within +-26.3 deg) only the part left of 20.5 deg is.
    at_60 = math.radians(60.0)
    x60, y60 = 2.0 * math.cos(at_60), 2.0 * math.sin(at_60)
    window = mapped(np.concatenate([wall(2.025, -1.0, 1.0), point(x60, y60)]), gimbal_yaw=at_60)
    assert cell(window, x60, y60) == OCCUPIED_CELL
    assert cell(window, 2.025, 0.025) == UNKNOWN_CELL  # base bearing 0.7 deg: -59.3 deg from the camera
    assert cell(window, 2.025, 0.975) == OCCUPIED_CELL  # base bearing 25.7 deg: -34.3 deg from the camera


def test_the_robot_pose_places_the_rays_in_the_episode_frame() -> None:
    # Robot at (1, 2) facing +y: base (2.025, b) is at (1 - b, 4.025), so the wall spans x in [0.5, 1.5].
    window = mapped(wall(2.025, -0.5, 0.5), pose=Pose(1.0, 2.0, math.pi / 2))
    for x in (0.575, 0.975, 1.025, 1.425):
        assert cell(window, x, 4.025) == OCCUPIED_CELL, x
    for x, y in [(0.975, 2.525), (1.025, 3.525), (0.975, 3.975)]:
        assert cell(window, x, y) == FREE_CELL, (x, y)
    assert cell(window, 3.025, 2.025) == UNKNOWN_CELL  # to the robot's right: unseen


def test_a_transient_obstacle_is_cleared_after_enough_free_observations() -> None:
    # A person 1 m ahead seen 5 times: 5 x 0.85 clamps to 3.5. Then the ray passes through to a wall at 3 m:
    # each update adds -0.4 -> after 7: 0.7 (occupied, >= 0.6), 8: 0.3 (unknown), 9: -0.1, 10: -0.5 (free).
    person = np.concatenate([wall(3.025, -1.0, 1.0), point(1.025, 0.025)])
    grid = LidarOccupancy()
    for _ in range(5):
        grid.update(person, ORIGIN)
    states = []
    for _ in range(10):
        grid.update(wall(3.025, -1.0, 1.0), ORIGIN)
        states.append(cell(grid.window(ORIGIN), 1.025, 0.025))
    assert states == [OCCUPIED_CELL] * 7 + [UNKNOWN_CELL] * 2 + [FREE_CELL]


def test_one_observation_marks_hits_occupied_and_crossed_cells_free() -> None:
    # One update: hit 0.85 >= 0.6 and miss -0.4 <= -0.4 (thresholds are inclusive).
    window = mapped(point(1.025, 0.025))
    assert cell(window, 1.025, 0.025) == OCCUPIED_CELL
    assert cell(window, 0.525, 0.025) == FREE_CELL


def test_a_cell_hit_and_crossed_in_one_update_counts_as_hit() -> None:
    # A grazing wall along the ray: each bin's nearest return is hit, and farther rays cross the nearer cells.
    ys = np.arange(0, 100) * 0.001
    scan = np.stack([1.0 + ys * 10.0, ys, np.full_like(ys, 0.5)], axis=1)
    window = mapped(scan.astype(np.float32))
    bearings, ranges = fov_ranges(scan, 0.0, LidarConfig())
    for bearing, distance in zip(bearings[np.isfinite(ranges)], ranges[np.isfinite(ranges)], strict=True):
        assert cell(window, distance * math.cos(bearing), distance * math.sin(bearing)) == OCCUPIED_CELL


def test_reset_forgets_everything() -> None:
    grid = LidarOccupancy()
    grid.update(wall(2.025, -1.0, 1.0), ORIGIN)
    grid.reset()
    assert (grid.window(ORIGIN).cells == UNKNOWN_CELL).all()


def test_the_grid_grows_as_the_robot_travels() -> None:
    grid = LidarOccupancy()
    grid.update(wall(2.025, -1.0, 1.0), ORIGIN)
    far = Pose(40.0, -30.0, 0.0)
    grid.update(wall(2.025, -1.0, 1.0), far)
    assert cell(grid.window(far), 42.025, -29.975) == OCCUPIED_CELL
    assert cell(grid.window(ORIGIN), 2.025, 0.025) == OCCUPIED_CELL  # the first observation is kept


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(-6.0, 6.0), st.floats(-6.0, 6.0), st.floats(0.0, 1.2)),
        min_size=0,
        max_size=30,
    ),
    st.floats(-math.pi, math.pi),
    st.floats(-math.pi, math.pi),
)
def test_known_cells_lie_in_the_camera_wedge(
    points: list[tuple[float, float, float]], yaw: float, gimbal_yaw: float
) -> None:
    # Every known cell's centre lies within the field of view of the camera axis, up to the angle a half cell
    # diagonal subtends (cells within 0.1 m of the robot excepted), and never beyond max_range plus a cell.
    config = LidarConfig(window=24.0)
    pose = Pose(0.3, -0.2, yaw)
    grid = LidarOccupancy(config)
    grid.update(np.array(points, dtype=np.float32).reshape(-1, 3), pose, gimbal_yaw)
    window = grid.window(pose)
    rows, cols = np.nonzero(window.cells != UNKNOWN_CELL)
    dx = window.origin[0] + (cols + 0.5) * config.resolution - pose.x
    dy = window.origin[1] + (rows + 0.5) * config.resolution - pose.y
    distance = np.hypot(dx, dy)
    assert distance.max() <= config.max_range + config.resolution
    far = distance > 0.1
    off_axis = np.abs((np.arctan2(dy, dx) - yaw - gimbal_yaw + math.pi) % (2 * math.pi) - math.pi)[far]
    margin = np.arcsin(np.minimum(1.0, config.resolution / math.sqrt(2.0) / distance[far]))
    assert (off_axis <= math.radians(39.5) + margin + 1e-9).all()
