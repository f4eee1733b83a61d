"""Frontier cells, grouping, pocket areas (hand-built maps) and frontiers of scanned synthetic rooms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivenav.grid import GridSpec
from drivenav.mapping.config import MappingConfig
from drivenav.mapping.frontiers import extract_frontiers, frontier_cells
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.synthetic import BoxWorld, room, wall
from drivenav.types import CameraIntrinsics, Pose, SimConfig

GRID = GridSpec(0.05, (0.0, 0.0), (100, 100))
SMALL = CameraIntrinsics.from_hfov(320, 240, 79.0)


def holed(hole: tuple[slice, slice]) -> np.ndarray:
    explored = np.ones(GRID.shape, dtype=np.bool_)
    explored[hole] = False
    return explored


def test_frontier_cells_are_navigable_cells_touching_unexplored_by_4_neighbours() -> None:
    explored = holed((slice(40, 60), slice(40, 60)))
    cells = frontier_cells(explored, explored)
    ring = np.zeros_like(explored)
    ring[39, 40:60] = ring[60, 40:60] = ring[40:60, 39] = ring[40:60, 60] = True
    ring[0, :] = ring[-1, :] = ring[:, 0] = ring[:, -1] = True  # beyond the array counts as unexplored
    np.testing.assert_array_equal(cells, ring)


@pytest.mark.parametrize(("min_area", "kept"), [(1.5, 0), (0.99, 1)])
def test_closed_pocket_area_is_exact_and_small_pockets_are_dropped(min_area: float, kept: int) -> None:
    explored = holed((slice(40, 60), slice(40, 60)))  # 20 x 20 cells = 1.0 m^2
    navigable = explored.copy()
    navigable[[0, -1], :] = navigable[:, [0, -1]] = False  # no frontier along the array border
    found = extract_frontiers(GRID, explored, navigable, np.zeros_like(explored), min_area=min_area, pocket_window=2.0)
    assert len(found) == kept
    if kept:
        f = found[0]
        assert f.unexplored_area == pytest.approx(1.0)
        assert len(f.cells) == 80  # four sides, one 8-connected ring
        np.testing.assert_allclose(f.points, GRID.cell_to_world(f.cells))
        assert any(np.allclose(f.waypoint, p) for p in f.points)
        centroid = f.points.mean(axis=0)
        dist = np.linalg.norm(f.points - centroid, axis=1)
        assert np.linalg.norm(np.array(f.waypoint) - centroid) == pytest.approx(dist.min())


def test_blocked_cells_do_not_count_in_the_pocket() -> None:
    explored = holed((slice(40, 60), slice(40, 60)))
    navigable = explored.copy()
    navigable[[0, -1], :] = navigable[:, [0, -1]] = False
    blocked = np.zeros_like(explored)
    blocked[40:60, 50:60] = True
    (f,) = extract_frontiers(GRID, explored, navigable, blocked, min_area=0.0, pocket_window=2.0)
    assert f.unexplored_area == pytest.approx(0.5)


def test_open_pocket_is_measured_inside_the_window() -> None:
    grid = GridSpec(0.05, (-5.0, -5.0), (200, 200))
    explored = np.zeros(grid.shape, dtype=np.bool_)
    explored[:, :50] = True
    navigable = explored.copy()
    navigable[[0, -1], :] = False
    navigable[:, 0] = False
    (f,) = extract_frontiers(grid, explored, navigable, np.zeros_like(explored), min_area=1.5, pocket_window=2.0)
    assert set(f.cells[:, 1]) == {49}
    np.testing.assert_allclose(f.points[:, 0], -5.0 + 49.5 * 0.05)
    # window: 40 columns beyond the frontier column, all 200 rows: 8000 cells = 20 m^2
    assert f.unexplored_area == pytest.approx(20.0)


def test_separate_frontiers_get_separate_ids() -> None:
    explored = holed((slice(20, 30), slice(20, 30)))
    explored[70:80, 70:80] = False
    navigable = explored.copy()
    navigable[[0, -1], :] = navigable[:, [0, -1]] = False
    found = extract_frontiers(GRID, explored, navigable, np.zeros_like(explored), min_area=0.0, pocket_window=1.0)
    assert [f.frontier_id for f in found] == [0, 1]
    assert found[0].waypoint[0] < found[1].waypoint[0]


def scan(world: BoxWorld, *spots: tuple[float, float], **overrides: float) -> OccupancyMapper:
    """Turn 360 degrees in 30-degree steps at each spot (default: the origin)."""
    mapper = OccupancyMapper(MappingConfig.from_sim(SimConfig(), **overrides))
    for x, y in spots or [(0.0, 0.0)]:
        for k in range(12):
            pose = Pose(x, y, k * math.pi / 6.0)
            mapper.update(world.render(pose, SMALL), SMALL, pose)
    return mapper


def door_world() -> BoxWorld:
    beyond = [wall(3, -3, 9, -3), wall(3, 3, 9, 3), wall(9, -3, 9, 3), wall(3, -3, 3, -2), wall(3, 2, 3, 3)]
    return BoxWorld(tuple(room(-3, -2, 3, 2, door_east=(-0.5, 0.5)) + beyond))


def test_scanned_closed_room_has_no_frontiers() -> None:
    mapper = scan(BoxWorld(tuple(room(-3, -2, 3, 2))))
    assert mapper.frontiers() == []
    snap = mapper.snapshot()
    assert snap.navigable.sum() * 0.0025 == pytest.approx((6 - 0.1 - 0.36) * (4 - 0.1 - 0.36), rel=0.1)


def test_half_explored_room_has_its_frontier_beyond_the_door() -> None:
    mapper = scan(door_world())
    found = mapper.frontiers()
    assert len(found) == 1
    f = found[0]
    assert f.points[:, 0].min() > 3.05  # past the east wall of the scanned room
    assert np.abs(f.points[:, 1]).max() < 1.0  # inside the cone seen through the 1 m door
    assert 3.05 < f.waypoint[0] < 5.1
    assert f.unexplored_area >= 1.5
    snap = mapper.snapshot()
    np.testing.assert_array_equal(snap.grid.cell_to_world(f.cells), f.points)
    assert snap.navigable[f.cells[:, 0], f.cells[:, 1]].all()


def test_shadow_pocket_behind_a_pillar_is_dropped_by_area() -> None:
    # A pillar in the middle of a room seen from two sides leaves a closed shadow pocket behind it.
    pillar = wall(1.5, -0.15, 1.5, 0.15, thickness=0.3)
    world = BoxWorld((*room(-3, -2, 3, 2), pillar))
    spots = [(0.0, 1.2), (0.0, -1.2)]
    assert scan(world, *spots).frontiers() == []
    tiny = scan(world, *spots, min_frontier_area=0.0).frontiers()
    assert tiny, "the pocket exists when nothing is dropped"
    for f in tiny:
        assert 0.0 < f.unexplored_area < 1.5
        assert np.linalg.norm(np.array(f.waypoint) - np.array([1.5, 0.0])) < 1.6
