"""LiDAR occupancy fused into the obstacle map (paper Sec. V-E: the real robot's LiDAR + IMU occupancy grid, kept
inside the camera's forward 79 deg) against hand-computed cells.

Unless a test says otherwise the map is 0.1 m cells, 40 x 40 with its origin at (-2, -2), so world ``(x, y)`` lies
in cell ``(row, col) = (floor((y + 2) / 0.1), floor((x + 2) / 0.1))`` and the agent at (0, 0) is in cell (20, 20).
Obstacles are inflated by 0.2 m = 2 cells: the 13 cells with ``di^2 + dj^2 <= 4``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivenav.agent.body import ExplorerAgent
from drivenav.envs.vocabulary import VOCABULARY
from drivenav.mapping.config import MappingConfig, MapTuning
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.synthetic import Box3, BoxWorld
from drivenav.mapping.types import MapSnapshot
from drivenav.settings import load_settings
from drivenav.types import (
    FREE_CELL,
    OCCUPIED_CELL,
    UNKNOWN_CELL,
    GroundTruth,
    LocalOccupancy,
    Observation,
    Pose,
    SimConfig,
)

CONFIG = MappingConfig(resolution=0.1, agent_radius=0.2, inflation_margin=0.0, initial_size=4.0, growth_margin=1.0)
DISK = [(di, dj) for di in range(-2, 3) for dj in range(-2, 3) if di * di + dj * dj <= 4]
SIM = SimConfig()
WALL = BoxWorld((Box3((2.02, 2.3), (-5.0, 5.0)),))  # depth obstacle cells at x in [2.00, 2.05)


def window(
    origin: tuple[float, float],
    shape: tuple[int, int],
    resolution: float = 0.1,
    occupied: tuple[tuple[int, int], ...] = (),
    unknown: tuple[tuple[int, int], ...] = (),
) -> LocalOccupancy:
    """A window of free cells but for the ``occupied`` and ``unknown`` (row, col) ones."""
    cells = np.full(shape, FREE_CELL, dtype=np.int8)
    for rc in occupied:
        cells[rc] = OCCUPIED_CELL
    for rc in unknown:
        cells[rc] = UNKNOWN_CELL
    return LocalOccupancy(cells, origin, resolution)


def block(rows: range, cols: range, minus: tuple[tuple[int, int], ...] = ()) -> set[tuple[int, int]]:
    return {(r, c) for r in rows for c in cols} - set(minus)


def cells_of(mask: np.ndarray) -> set[tuple[int, int]]:
    return {(int(r), int(c)) for r, c in np.argwhere(mask)}


def world_points(snapshot: MapSnapshot, mask: np.ndarray) -> set[tuple[float, float]]:
    return {(round(float(x), 6), round(float(y), 6)) for x, y in snapshot.grid.cell_to_world(np.argwhere(mask))}


# Window A: 20 x 20 free cells over [-1, 1)^2 (map rows and columns 10..29); its cell (10, 15) is occupied, centre
# (-1 + 15.5 * 0.1, -1 + 10.5 * 0.1) = (0.55, 0.05): map cell (20, 25).
WINDOW_A = window((-1.0, -1.0), (20, 20), occupied=((10, 15),))
A_OBSTACLE = (20, 25)
A_DISK = tuple((20 + di, 25 + dj) for di, dj in DISK)


def test_an_occupied_lidar_cell_is_an_obstacle_and_its_disk_leaves_navigable() -> None:
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(WINDOW_A)
    snap = mapper.snapshot()
    assert cells_of(snap.obstacle) == {A_OBSTACLE}
    assert cells_of(snap.explored) == block(range(10, 30), range(10, 30), minus=(A_OBSTACLE,))
    assert cells_of(snap.navigable) == block(range(10, 30), range(10, 30), minus=A_DISK)
    assert mapper.last_update is not None and mapper.last_update.accepted
    assert (mapper.last_update.new_obstacle_cells, mapper.last_update.grew) == (1, False)


def test_free_lidar_cells_are_explored_and_unknown_ones_are_not() -> None:
    # 3 x 5 cells over x in [-0.2, 0.3), y in [-0.1, 0.2): map rows 19..21, columns 18..22; its unknown cell
    # (2, 4) is map cell (21, 22).
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(window((-0.2, -0.1), (3, 5), unknown=((2, 4),)))
    snap = mapper.snapshot()
    assert cells_of(snap.explored) == block(range(19, 22), range(18, 23), minus=((21, 22),))
    assert cells_of(snap.navigable) == cells_of(snap.explored)
    assert not snap.obstacle.any()


@pytest.mark.parametrize(
    ("resolution", "shape", "occupied"),
    [
        (0.12, (10, 10), (5, 8)),  # coarser: centre (0.42, 0.06); map cells' centres never fall in a gap
        (0.06, (20, 20), (10, 17)),  # finer: centre (0.45, 0.03)
    ],
)
def test_other_resolutions_leave_no_gaps_and_lose_no_obstacle(
    resolution: float, shape: tuple[int, int], occupied: tuple[int, int]
) -> None:
    # Both windows cover [-0.6, 0.6)^2: the map cells whose centres lie there are rows and columns 14..25. The
    # occupied cell's centre is in map cell (20, 24), whose own centre (0.45, 0.05) lies in that occupied cell.
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(window((-0.6, -0.6), shape, resolution, occupied=(occupied,)))
    snap = mapper.snapshot()
    assert cells_of(snap.obstacle) == {(20, 24)}
    assert cells_of(snap.explored) == block(range(14, 26), range(14, 26), minus=((20, 24),))


def test_a_lidar_obstacle_seen_free_later_is_cleared_with_its_whole_disk() -> None:
    # The second window is the obstacle's cell alone; its disk reaches two cells beyond it and must go too.
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(WINDOW_A)
    mapper.fuse_occupancy(window((0.5, 0.0), (1, 1)))
    snap = mapper.snapshot()
    assert not snap.obstacle.any()
    assert cells_of(snap.navigable) == block(range(10, 30), range(10, 30))


def test_a_window_beside_an_obstacle_keeps_the_part_of_its_disk_it_reaches() -> None:
    # The second window is map cell (20, 22) alone, 3 cells west of A's obstacle: the obstacle lies outside the
    # cells whose inflation the window can change (2 cells around it) but its disk reaches into them -- (20, 23),
    # (20, 24), (19, 24), (21, 24) -- and must stay.
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(WINDOW_A)
    mapper.fuse_occupancy(window((0.2, 0.0), (1, 1)))
    assert cells_of(mapper.snapshot().navigable) == block(range(10, 30), range(10, 30), minus=A_DISK)


def test_lidar_clears_its_own_obstacles_but_never_depth_ones() -> None:
    # Map of the simulator (0.05 m cells, origin (-10, -10)): the wall face at x = 2.02 is depth obstacle column
    # 240. The window covers x in [1.5, 2.5), y in [-0.5, 0.5): map rows 190..209, columns 230..249; its occupied
    # cells (10, 5) and (10, 10) have centres (1.775, 0.025) and (2.025, 0.025): map cells (200, 235) and
    # (200, 240), the latter on the wall. Cell (200, 235) is 5 cells from the wall, beyond its 4.6-cell inflation.
    pose = Pose(0.0, 0.0, 0.0)
    depth_only = OccupancyMapper(MappingConfig.from_sim(SIM))
    depth_only.update(WALL.render(pose, SIM.intrinsics), SIM.intrinsics, pose)
    fused = OccupancyMapper(MappingConfig.from_sim(SIM))
    fused.update(WALL.render(pose, SIM.intrinsics), SIM.intrinsics, pose)
    fused.fuse_occupancy(window((1.5, -0.5), (20, 20), 0.05, occupied=((10, 5), (10, 10))))
    seen = fused.snapshot()
    assert seen.obstacle[200, 235] and seen.obstacle[200, 240]
    assert depth_only.snapshot().navigable[200, 235] and not seen.navigable[200, 235]
    fused.fuse_occupancy(window((1.5, -0.5), (20, 20), 0.05))  # the person walked away: all free
    cleared, expected = fused.snapshot(), depth_only.snapshot()
    np.testing.assert_array_equal(cleared.obstacle, expected.obstacle)
    assert cleared.obstacle[200, 240] and not cleared.obstacle[200, 235]
    # What the LiDAR explored beyond depth lies behind the inflated wall, cut off from the agent.
    np.testing.assert_array_equal(cleared.navigable, expected.navigable)


def test_a_window_beyond_the_grid_grows_it_and_keeps_the_lidar_layers_in_place() -> None:
    # Window B over x in [-6, -5), y in [-0.5, 0.5) lies west of the grid's [-2, 2): the origin moves and every
    # layer shifts; B's occupied cell (0, 0) has centre (-5.95, -0.45). B is cut off from the agent, so the
    # navigable cells (in world coordinates) stay those around A's obstacle.
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(WINDOW_A)
    before = mapper.snapshot()
    mapper.fuse_occupancy(window((-6.0, -0.5), (10, 10), occupied=((0, 0),)))
    after = mapper.snapshot()
    assert mapper.last_update is not None and mapper.last_update.accepted and mapper.last_update.grew
    assert after.grid.origin[0] < -6.0 and after.grid.shape[1] > before.grid.shape[1]
    assert world_points(after, after.obstacle) == {(0.55, 0.05), (-5.95, -0.45)}
    assert world_points(after, after.navigable) == world_points(before, before.navigable)


@pytest.mark.parametrize(
    ("resolution", "origin", "accepted", "reason"),
    [
        (0.25, (-1.0, -1.0), False, "factor 2"),
        (0.049, (-1.0, -1.0), False, "factor 2"),
        (math.nan, (-1.0, -1.0), False, "factor 2"),
        (0.1, (math.inf, -1.0), False, "origin"),
        (0.2, (-1.0, -1.0), True, ""),
        (0.05, (-1.0, -1.0), True, ""),
    ],
)
def test_a_window_off_by_more_than_a_factor_2_or_nowhere_is_refused(
    resolution: float, origin: tuple[float, float], accepted: bool, reason: str
) -> None:
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(window(origin, (4, 4), resolution, occupied=((1, 1),)))
    assert mapper.last_update is not None
    assert mapper.last_update.accepted == accepted and reason in mapper.last_update.reason
    assert mapper.snapshot().obstacle.any() == accepted


def test_empty_or_non_integer_cells_are_refused() -> None:
    mapper = OccupancyMapper(CONFIG)
    for cells in (np.zeros((0, 3), dtype=np.int8), np.zeros((3, 3), dtype=np.float32), np.zeros(3, dtype=np.int8)):
        mapper.fuse_occupancy(LocalOccupancy(cells, (0.0, 0.0), 0.1))  # type: ignore[arg-type]
        assert mapper.last_update is not None and not mapper.last_update.accepted
        assert "2-D integer array" in mapper.last_update.reason


def test_reset_forgets_the_lidar_layers() -> None:
    mapper = OccupancyMapper(CONFIG)
    mapper.fuse_occupancy(WINDOW_A)
    mapper.reset()
    mapper.fuse_occupancy(window((-1.0, -1.0), (20, 20), unknown=((10, 15),)))
    assert not mapper.snapshot().obstacle.any()
    assert cells_of(mapper.snapshot().navigable) == block(range(10, 30), range(10, 30), minus=(A_OBSTACLE,))


def test_fuse_lidar_is_a_mapping_key_off_by_default() -> None:
    assert not load_settings().mapping.fuse_lidar
    tuned = load_settings(overrides=["mapping.fuse_lidar=true"]).mapping
    assert tuned.fuse_lidar and MappingConfig.from_sim(SIM, tuned).fuse_lidar


def _agent_maps(fuse_lidar: bool, occupancy: LocalOccupancy | None) -> tuple[MapSnapshot, int]:
    """The agent's maps after one step at the origin facing the wall, and its frontier count."""
    agent = ExplorerAgent(SIM, mapping=MapTuning(fuse_lidar=fuse_lidar))
    agent.reset("chair", 0, GroundTruth({}, VOCABULARY))
    pose, k = Pose(0.0, 0.0, 0.0), SIM.intrinsics
    rgb, semantic = np.zeros((k.height, k.width, 3), np.uint8), np.zeros((k.height, k.width), np.int32)
    agent.decide(Observation(rgb, WALL.render(pose, k), semantic, pose, k, 0, False, occupancy))
    assert agent.state is not None
    return agent.state.mapper.snapshot(), len(agent.state.mapper.frontiers())


def test_the_agent_fuses_lidar_only_when_switched_on() -> None:
    # The window's occupied cell (10, 5) is map cell (200, 235), 1.775 m ahead: no depth obstacle there.
    lidar = window((1.5, -0.5), (20, 20), 0.05, occupied=((10, 5),))
    plain, plain_frontiers = _agent_maps(False, None)
    for fuse_lidar, occupancy in ((False, lidar), (True, None)):
        maps, frontiers = _agent_maps(fuse_lidar, occupancy)
        for layer in ("obstacle", "explored", "navigable"):
            np.testing.assert_array_equal(getattr(maps, layer), getattr(plain, layer))
        assert maps.grid == plain.grid and frontiers == plain_frontiers
    fused, _ = _agent_maps(True, lidar)
    assert cells_of(fused.obstacle) == cells_of(plain.obstacle) | {(200, 235)}
