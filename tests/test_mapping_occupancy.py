"""Geometry of the obstacle / explored / navigable maps against hand-computed cells."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivenav.mapping.config import MappingConfig
from drivenav.mapping.occupancy import OccupancyMapper, disk_offsets
from drivenav.mapping.synthetic import Box3, BoxWorld
from drivenav.mapping.types import MapSnapshot
from drivenav.types import CameraIntrinsics, Pose, SimConfig

SIM = SimConfig()
K = SIM.intrinsics  # 640 x 480, hfov 79 deg: f = 320 / tan(39.5 deg) = 388.19, cx = 319.5, cy = 239.5
HALF_FOV = math.radians(39.5)


def mapped(world: BoxWorld, *poses: Pose, config: MappingConfig | None = None) -> OccupancyMapper:
    mapper = OccupancyMapper(config or MappingConfig.from_sim(SIM))
    for pose in poses:
        mapper.update(world.render(pose, K), K, pose)
    return mapper


def at(snapshot: MapSnapshot, layer: str, x: float, y: float) -> bool:
    row, col = snapshot.grid.world_to_cell((x, y))
    return bool(getattr(snapshot, layer)[row, col])


def obstacle_points(snapshot: MapSnapshot) -> np.ndarray:
    return snapshot.grid.cell_to_world(np.argwhere(snapshot.obstacle))


def test_wall_straight_ahead_lands_in_one_column() -> None:
    # Wall face at x = 2.02: obstacle cells cover x in [2.00, 2.05); the image spans |y| <= 2.02 tan(39.5).
    snap = mapped(BoxWorld((Box3((2.02, 2.3), (-5.0, 5.0)),)), Pose(0.0, 0.0, 0.0)).snapshot()
    pts = obstacle_points(snap)
    np.testing.assert_allclose(pts[:, 0], 2.025)
    half_width = 2.02 * math.tan(HALF_FOV)  # 1.665 m
    assert pts[:, 1].max() == pytest.approx(half_width, abs=0.06)
    assert pts[:, 1].min() == pytest.approx(-half_width, abs=0.06)
    assert len(np.unique(pts[:, 1])) == len(pts)  # one cell per row ...
    assert len(pts) >= int(2 * half_width / 0.05) - 1  # ... and no row missing


def test_hand_made_depth_patch_left_of_centre_maps_to_the_left() -> None:
    # Columns u in [100, 110] read 2.02 m from the horizon down to height 0.15 m: kx = (cx - u) / f, so the
    # points are at forward 2.02 m and left 2.02 * kx in [1.090, 1.142] m.
    depth = np.full((480, 640), 5.0, dtype=np.float32)
    depth[240:381, 100:111] = 2.02
    f = 320.0 / math.tan(HALF_FOV)
    left = 2.02 * (319.5 - np.arange(100, 111)) / f
    for pose, forward, lateral in [
        (Pose(0.0, 0.0, 0.0), (1, 0), (0, 1)),
        (Pose(1.0, 2.0, math.pi / 2), (0, 1), (-1, 0)),
    ]:
        mapper = OccupancyMapper(MappingConfig.from_sim(SIM))
        mapper.update(depth, K, pose)
        pts = obstacle_points(mapper.snapshot())
        expected = np.array([pose.x, pose.y]) + 2.02 * np.array(forward) + np.outer(left, lateral)
        cells = {tuple(c) for c in mapper.grid.world_to_cell(expected)}
        assert {tuple(c) for c in mapper.grid.world_to_cell(pts)} == cells


def test_wall_to_the_left_with_turned_agent() -> None:
    # Facing +y (yaw 90 deg) from (1, -0.5): the wall face at y = 2.52 is 3.02 m ahead, the view spans
    # x in 1 -/+ 3.02 tan(39.5) = [-1.49, 3.49].
    world = BoxWorld((Box3((-5.0, 5.0), (2.52, 2.8)),))
    pts = obstacle_points(mapped(world, Pose(1.0, -0.5, math.pi / 2)).snapshot())
    np.testing.assert_allclose(pts[:, 1], 2.525)
    assert pts[:, 0].min() == pytest.approx(1.0 - 3.02 * math.tan(HALF_FOV), abs=0.06)
    assert pts[:, 0].max() == pytest.approx(1.0 + 3.02 * math.tan(HALF_FOV), abs=0.06)
    turned_away = mapped(world, Pose(1.0, -0.5, -math.pi / 2)).snapshot()
    assert not turned_away.obstacle.any()


def test_floor_is_not_an_obstacle_and_is_explored_to_max_depth_in_the_fov() -> None:
    snap = mapped(BoxWorld(()), Pose(0.0, 0.0, 0.0)).snapshot()
    assert not snap.obstacle.any()
    for x, y in [(0.6, 0.0), (4.9, 0.0), (3.0, 2.0), (3.0, -2.0), (1.0, 0.0)]:
        assert at(snap, "explored", x, y), (x, y)
    for x, y in [(5.2, 0.0), (3.0, 2.8), (3.0, -2.8), (-0.5, 0.0), (-3.0, 1.0), (0.0, 1.0)]:
        assert not at(snap, "explored", x, y), (x, y)


def test_low_clutter_below_the_band_is_floor() -> None:
    snap = mapped(BoxWorld((Box3((1.5, 2.5), (-0.5, 0.5), (0.0, 0.1)),)), Pose(0.0, 0.0, 0.0)).snapshot()
    assert not snap.obstacle.any()
    high = mapped(BoxWorld((Box3((1.5, 2.5), (-0.5, 0.5), (0.0, 0.3)),)), Pose(0.0, 0.0, 0.0)).snapshot()
    assert at(high, "obstacle", 1.52, 0.0)


def test_cells_behind_an_obstacle_and_behind_the_agent_stay_unexplored() -> None:
    snap = mapped(BoxWorld((Box3((2.02, 2.3), (-0.5, 0.5)),)), Pose(0.0, 0.0, 0.0)).snapshot()
    assert at(snap, "explored", 2.03, 0.0)  # the hit cell itself
    assert not at(snap, "explored", 3.0, 0.0)
    assert not at(snap, "explored", 2.6, 0.3)
    assert at(snap, "explored", 3.0, 1.5)  # beside the obstacle, inside the field of view
    assert not at(snap, "explored", -1.0, 0.0)


@pytest.mark.parametrize("value", [5.0, 4.995, 0.5, 0.505])
def test_clip_limit_readings_add_no_obstacles(value: float) -> None:
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM))
    mapper.update(np.full((480, 640), value, dtype=np.float32), K, Pose(0.0, 0.0, 0.0))
    snap = mapper.snapshot()
    assert not snap.obstacle.any()
    if value < 1.0:  # something closer than the minimum depth: nothing beyond the footprint is explored
        assert snap.explored.sum() == len(disk_offsets(0.18, 0.05))


def test_just_inside_the_depth_range_is_an_obstacle() -> None:
    depth = np.full((480, 640), 5.0, dtype=np.float32)
    depth[240:300, 300:340] = 4.9
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM))
    mapper.update(depth, K, Pose(0.0, 0.0, 0.0))
    assert at(mapper.snapshot(), "obstacle", 4.92, 0.0)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 0.0, -1.0])
def test_holes_change_nothing(bad: float) -> None:
    world = BoxWorld((Box3((2.02, 2.3), (-5.0, 5.0)),))
    pose = Pose(0.3, -0.2, 0.4)
    mapper = mapped(world, pose)
    before = mapper.snapshot()
    good = world.render(pose, K)
    holes = good.copy()
    holes[::3] = bad  # a third of the rows are holes: the rest still maps the same wall
    mapper.update(holes, K, pose)
    mapper.update(np.full_like(good, bad), K, pose)
    after = mapper.snapshot()
    for layer in ("obstacle", "explored", "navigable"):
        np.testing.assert_array_equal(getattr(after, layer), getattr(before, layer))


@pytest.mark.parametrize(
    "depth",
    [
        np.full((480, 640), 2, dtype=np.int16),
        np.full((480, 640), 2.0, dtype=np.complex64),
        np.ones((480, 640), dtype=np.bool_),
        np.full((240, 320), 2.0, dtype=np.float32),
        np.full((480, 640, 1), 2.0, dtype=np.float32),
        [[2.0] * 640] * 480,
        None,
    ],
)
def test_malformed_frames_are_ignored(depth: object) -> None:
    mapper = OccupancyMapper()
    mapper.update(depth, K, Pose(0.0, 0.0, 0.0))  # type: ignore[arg-type]
    assert mapper.last_update is not None
    assert not mapper.last_update.accepted and mapper.last_update.reason
    assert not mapper.snapshot().explored.any()


def test_float64_depth_and_non_finite_pose() -> None:
    depth = BoxWorld((Box3((2.02, 2.3), (-5.0, 5.0)),)).render(Pose(0.0, 0.0, 0.0), K)
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM))
    mapper.update(depth, K, Pose(math.nan, 0.0, 0.0))
    assert mapper.last_update is not None and not mapper.last_update.accepted
    mapper.update(depth.astype(np.float64), K, Pose(0.0, 0.0, 0.0))
    assert at(mapper.snapshot(), "obstacle", 2.03, 0.0)


def test_navigable_excludes_the_agent_radius_band() -> None:
    # Obstacle column centres at x = 2.025; inflation 0.18 m + one cell (from_sim) = 0.23 m: centre 1.825 is
    # 0.20 m away (blocked), 1.775 is 0.25 m away (free).
    snap = mapped(BoxWorld((Box3((2.02, 2.3), (-5.0, 5.0)),)), Pose(0.0, 0.0, 0.0)).snapshot()
    assert at(snap, "navigable", 1.78, 0.0)
    assert at(snap, "navigable", 1.78, 0.6)
    assert not at(snap, "navigable", 1.83, 0.0)
    assert not at(snap, "navigable", 1.88, 0.0)
    assert not at(snap, "navigable", 2.03, 0.0)
    assert at(snap, "navigable", 0.0, 0.0)
    assert not (snap.navigable & ~snap.explored).any()
    assert not (snap.navigable & snap.obstacle).any()


def test_disk_offsets_by_hand() -> None:
    # radius 3.6 cells: (3, 1) is inside (10 <= 12.96), (3, 2) is not (13 > 12.96).
    offsets = {tuple(o) for o in disk_offsets(0.18, 0.05)}
    assert (3, 1) in offsets and (0, 3) in offsets
    assert (3, 2) not in offsets and (0, 4) not in offsets
    assert len(offsets) == 37


def test_map_grows_when_the_agent_walks_off_it() -> None:
    config = MappingConfig.from_sim(SIM, initial_size=4.0, growth_margin=2.0)
    world = BoxWorld((Box3((2.02, 2.3), (-1.0, 1.0)), Box3((14.02, 14.3), (-1.0, 1.0))))
    mapper = mapped(world, Pose(0.0, 0.0, 0.0), config=config)
    first = mapper.snapshot()
    assert first.grid.shape[1] * 0.05 >= 2 * 6.4  # grown to hold the sensor range
    mapper.update(world.render(Pose(12.0, 0.0, 0.0), K), K, Pose(12.0, 0.0, 0.0))
    assert mapper.last_update is not None and mapper.last_update.grew
    second = mapper.snapshot()
    shift = (np.array(first.grid.origin) - np.array(second.grid.origin)) / 0.05
    np.testing.assert_allclose(shift, np.round(shift), atol=1e-6)  # cells stay aligned
    old = {tuple(np.round(p, 3)) for p in obstacle_points(first)}
    new = {tuple(np.round(p, 3)) for p in obstacle_points(second)}
    assert old < new
    assert at(second, "obstacle", 14.03, 0.0)
    mapper.update(world.render(Pose(90.0, -70.0, 2.0), K), K, Pose(90.0, -70.0, 2.0))
    assert at(mapper.snapshot(), "explored", 90.0, -70.0)


def test_pose_jump_past_max_size_is_ignored() -> None:
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM, max_size=60.0))
    depth = np.full((480, 640), 2.0, dtype=np.float32)
    mapper.update(depth, K, Pose(1e4, 0.0, 0.0))
    assert mapper.last_update is not None and not mapper.last_update.accepted
    assert "max_size" in mapper.last_update.reason
    mapper.update(depth, K, Pose(20.0, 0.0, 0.0))  # 20 + 6.5 + 5 margin on one side, 10 on the other
    assert mapper.last_update is not None and mapper.last_update.accepted
    assert mapper.grid.shape[1] * 0.05 <= 60.0


def test_snapshot_is_read_only() -> None:
    snap = OccupancyMapper().snapshot()
    with pytest.raises(ValueError):
        snap.obstacle[0, 0] = True


def test_small_image_still_explores_without_gaps() -> None:
    small = CameraIntrinsics.from_hfov(64, 48, 79.0)
    mapper = OccupancyMapper(MappingConfig.from_sim(SIM))
    pose = Pose(0.0, 0.0, 0.0)
    mapper.update(BoxWorld(()).render(pose, small), small, pose)
    snap = mapper.snapshot()
    angles = np.radians(np.linspace(-38.0, 38.0, 200))
    ring = 4.8 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    assert all(at(snap, "explored", x, y) for x, y in ring)
