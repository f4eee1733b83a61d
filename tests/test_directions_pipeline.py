"""End-to-end checks of the directions pipeline on hand-built maps whose answers follow from the geometry."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from drivenav.directions.bench import bench_directions
from drivenav.directions.clustering import circular_distance
from drivenav.directions.pipeline import DirectionPipeline, _frontier_cells
from drivenav.directions.speed import build_speed_field
from drivenav.directions.synthetic import extract_frontiers, make_snapshot, rect
from drivenav.directions.types import DirectionResult
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import DirectionConfig, DriveNavConfig, SpeedFieldConfig
from drivenav.viz.directions import draw_directions

RES = 0.05
DEG = math.pi / 180.0


def _scene(free: np.ndarray, explored: np.ndarray) -> tuple[MapSnapshot, list[Frontier]]:
    snapshot = make_snapshot(free, explored, RES, inflation=0.15)
    return snapshot, extract_frontiers(snapshot)


def _frontier_near(frontiers: list[Frontier], x: float, y: float) -> int:
    dists = [math.hypot(f.waypoint[0] - x, f.waypoint[1] - y) for f in frontiers]
    return frontiers[int(np.argmin(dists))].frontier_id


def _direction_of(result: DirectionResult, frontier_id: int) -> int:
    return next(d.label for d in result.directions if frontier_id in d.frontier_ids)


def t_junction() -> tuple[MapSnapshot, list[Frontier]]:
    """Three 1 m corridors meeting at (4, 4): east, north and south; explored 2.5 m along each."""
    free = np.zeros((160, 160), np.bool_)
    explored = np.zeros_like(free)
    rect(free, 3.5, 0.0, 4.5, 8.0)  # north-south corridor
    rect(free, 4.5, 3.5, 8.0, 4.5)  # east arm
    rect(explored, 3.3, 1.5, 6.5, 6.5)
    return _scene(free, explored)


def side_door_corridor() -> tuple[MapSnapshot, list[Frontier]]:
    """A 1 m corridor along y = 2.5 (closed at x = 1) with doors in its north wall at x = 4-4.9 and 7-7.9,
    explored up to x = 9 and 0.3 m into each doorway."""
    free = np.zeros((120, 240), np.bool_)
    explored = np.zeros_like(free)
    rect(free, 1.0, 2.0, 11.0, 3.0)
    rect(free, 4.0, 3.0, 4.9, 5.0)
    rect(free, 7.0, 3.0, 7.9, 5.0)
    rect(explored, 0.8, 1.8, 9.0, 3.2)
    rect(explored, 3.8, 3.0, 5.1, 3.3)
    rect(explored, 6.8, 3.0, 8.1, 3.3)
    return _scene(free, explored)


def walled_room() -> tuple[MapSnapshot, list[Frontier]]:
    """A room x in [0.5, 5.5], y in [0.5, 6.5] split by a wall at x = 3 from the floor up to y = 5; free space
    continues east of x = 5.5, which is unexplored."""
    free = np.zeros((140, 160), np.bool_)
    explored = np.zeros_like(free)
    rect(free, 0.5, 0.5, 7.5, 6.5)
    wall = np.zeros_like(free)
    rect(wall, 2.9, 0.5, 3.1, 5.0)
    free &= ~wall
    rect(explored, 0.3, 0.3, 5.5, 6.7)
    return _scene(free, explored)


def test_t_junction_gives_three_directions_along_the_arms() -> None:
    snapshot, frontiers = t_junction()
    assert len(frontiers) == 3
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, (4.0, 4.0))
    assert result.unreachable == ()
    bearings = [d.bearing for d in result.directions]
    assert len(bearings) == 3
    for want in (0.0, 90.0, 270.0):
        assert min(circular_distance(got, want * DEG) for got in bearings) < 4.0 * DEG
    assert [d.label for d in result.directions] == [0, 1, 2]
    for path in result.paths.values():
        assert math.hypot(path.bearing_point[0] - 4.0, path.bearing_point[1] - 4.0) == pytest.approx(0.8)


def test_corridor_doors_share_the_corridor_direction_until_the_robot_reaches_them() -> None:
    snapshot, frontiers = side_door_corridor()
    assert len(frontiers) == 3
    door1 = _frontier_near(frontiers, 4.45, 3.3)
    door2 = _frontier_near(frontiers, 7.45, 3.3)
    end = _frontier_near(frontiers, 9.0, 2.5)
    pipeline = DirectionPipeline(DriveNavConfig())

    far = pipeline.update(snapshot, frontiers, (2.0, 2.5))
    assert len(far.directions) == 1
    (corridor,) = far.directions
    assert set(corridor.frontier_ids) == {door1, door2, end}
    assert circular_distance(corridor.bearing, 0.0) < 4.0 * DEG

    # In front of door 1 it splits off (fresh label); the corridor keeps its label by angle.
    near = pipeline.update(snapshot, frontiers, (4.45, 2.5))
    assert len(near.directions) == 2
    assert _direction_of(near, door2) == _direction_of(near, end) == corridor.label
    assert _direction_of(near, door1) == 1
    assert circular_distance(near.paths[door1].bearing, 90.0 * DEG) < 4.0 * DEG

    # Back at x = 2 both merge again: their waypoints match two previous directions -> both retired.
    merged = pipeline.update(snapshot, frontiers, (2.0, 2.5))
    assert [d.label for d in merged.directions] == [2]


def test_path_bearing_bends_around_a_wall_and_the_ablation_uses_the_straight_line() -> None:
    snapshot, frontiers = walled_room()
    robot = (1.5, 3.0)
    east = [f for f in frontiers if min(f.points[:, 0]) > 5.0]
    assert len(east) == 1
    fid = east[0].frontier_id
    straight = math.atan2(east[0].waypoint[1] - robot[1], east[0].waypoint[0] - robot[0]) % (2 * math.pi)

    result = DirectionPipeline(DriveNavConfig()).update(snapshot, east, robot)
    path = result.paths[fid]
    assert 30.0 * DEG < path.bearing < 85.0 * DEG  # towards the gap above the wall (3, 5-6.5)
    assert circular_distance(path.bearing, straight) > 25.0 * DEG
    assert max(path.path[:, 1]) > 5.0  # the path really goes over the wall's end

    config = DriveNavConfig(directions=DirectionConfig(path_bearings=False))
    ablated = DirectionPipeline(config).update(snapshot, east, robot)
    assert ablated.paths[fid].bearing == pytest.approx(straight, abs=1e-12)
    assert ablated.paths[fid].bearing_point == east[0].waypoint


def test_uniform_speed_ablation_takes_the_shorter_path_hugging_the_wall() -> None:
    snapshot, frontiers = walled_room()
    east = [f for f in frontiers if min(f.points[:, 0]) > 5.0]
    robot = (1.5, 3.0)
    weighted = DirectionPipeline(DriveNavConfig()).update(snapshot, east, robot)
    uniform_cfg = DriveNavConfig(speed=SpeedFieldConfig(weighted=False))
    uniform = DirectionPipeline(uniform_cfg).update(snapshot, east, robot)
    fid = east[0].frontier_id

    def length(points: np.ndarray) -> float:
        return float(np.hypot(*np.diff(points, axis=0).T).sum())

    assert length(uniform.paths[fid].path) < length(weighted.paths[fid].path)
    # Uniform speed: the arrival time is the geodesic length (up to the first-order FMM's bias).
    assert uniform.paths[fid].travel_time == pytest.approx(length(uniform.paths[fid].path), rel=0.08)
    assert uniform.timings_ms["skeleton"] == 0.0


def test_unreachable_frontiers_are_dropped_and_listed() -> None:
    snapshot, frontiers = t_junction()
    island = np.array([[20, 150], [21, 150]], dtype=np.int64)
    lonely = Frontier(99, snapshot.grid.cell_to_world(island), island, (7.525, 1.025), 1.0)
    navigable = snapshot.navigable.copy()
    navigable[20:22, 150] = True  # explored free cells, cut off from the robot
    cut_off = dataclasses.replace(snapshot, navigable=navigable)
    result = DirectionPipeline(DriveNavConfig()).update(cut_off, [*frontiers, lonely], (4.0, 4.0))
    assert result.unreachable == (99,)
    assert 99 not in result.paths
    assert len(result.directions) == 3


def test_no_frontiers_clears_the_directions() -> None:
    snapshot, frontiers = t_junction()
    pipeline = DirectionPipeline(DriveNavConfig())
    assert len(pipeline.update(snapshot, frontiers, (4.0, 4.0)).directions) == 3
    assert pipeline.update(snapshot, [], (4.0, 4.0)).directions == ()
    pipeline.reset()
    assert [d.label for d in pipeline.update(snapshot, frontiers, (4.0, 4.0)).directions] == [0, 1, 2]


def test_robot_in_the_inflation_band_is_snapped_to_traversable_space() -> None:
    snapshot, frontiers = t_junction()
    robot = (3.58, 4.0)  # 8 cm from the west wall: explored free, but not navigable
    cell = tuple(snapshot.grid.world_to_cell(robot))
    assert not snapshot.navigable[cell]
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, robot)
    assert len(result.paths) == 3
    for path in result.paths.values():
        assert tuple(path.path[0]) == robot


def test_debug_picture_is_written(tmp_path: Path) -> None:
    snapshot, frontiers = side_door_corridor()
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, (4.45, 2.5))
    out = tmp_path / "directions.png"
    draw_directions(snapshot, frontiers, result, (4.45, 2.5), out)
    from PIL import Image

    with Image.open(out) as image:
        assert image.size == (snapshot.grid.shape[1] * 2, snapshot.grid.shape[0] * 2)


def test_bench_reports_the_contract_fields() -> None:
    report = bench_directions(repeats=2)
    assert report["map_cells"] == 480 * 480
    assert report["map_shape"] == [480, 480]
    assert report["frontiers"] >= 10
    assert report["directions"] >= 3
    assert set(report["breakdown_ms"]) == {
        "distance_transforms",
        "skeleton",
        "fmm",
        "backtracking",
        "clustering",
        "tracking",
    }
    assert report["median_ms"] > 0.0
    assert report["skfmm_ms"] > 0.0
    assert report["ratio_vs_skfmm"] == report["breakdown_ms"]["fmm"] / report["skfmm_ms"]
    # The early-stopping solve settles part of what scikit-fmm solves (the whole region reachable from the robot).
    assert 0 < report["fmm_cells"] <= report["skfmm_cells"] <= report["explored_cells"]
    assert report["fmm_ns_per_cell"] == pytest.approx(report["breakdown_ms"]["fmm"] * 1e6 / report["fmm_cells"])
    assert report["skfmm_ns_per_cell"] == pytest.approx(report["skfmm_ms"] * 1e6 / report["skfmm_cells"])
    explored = report["mostly_explored"]
    assert explored["explored_cells"] > 1.5 * report["explored_cells"]
    assert explored["median_ms"] > 0.0 and explored["directions"] >= 1
    assert set(explored["breakdown_ms"]) == set(report["breakdown_ms"])


def _copy_snapshot(snapshot: MapSnapshot) -> MapSnapshot:
    return MapSnapshot(snapshot.grid, snapshot.obstacle.copy(), snapshot.explored.copy(), snapshot.navigable.copy())


def _same_result(a: DirectionResult, b: DirectionResult) -> None:
    assert len(a.directions) == len(b.directions)
    for d, e in zip(a.directions, b.directions, strict=True):
        assert (d.label, d.bearing, d.frontier_ids, d.farthest_point) == (
            e.label,
            e.bearing,
            e.frontier_ids,
            e.farthest_point,
        )
        np.testing.assert_array_equal(d.waypoints, e.waypoints)
    assert a.unreachable == b.unreachable
    assert a.paths.keys() == b.paths.keys()
    for key, path in a.paths.items():
        other = b.paths[key]
        np.testing.assert_array_equal(path.path, other.path)
        assert (path.bearing, path.travel_time, path.farthest_point) == (
            other.bearing,
            other.travel_time,
            other.farthest_point,
        )


@pytest.mark.parametrize("robot", [(4.0, 4.0), (4.0, 3.0), (5.5, 4.0)])
def test_a_reused_speed_field_gives_what_a_fresh_pipeline_gives(robot: tuple[float, float]) -> None:
    """An unchanged map (equal content, new arrays) reuses the speed field; the robot may have moved."""
    snapshot, frontiers = t_junction()
    pipeline = DirectionPipeline(DriveNavConfig())
    pipeline.update(snapshot, frontiers, (4.0, 4.0))
    again = _copy_snapshot(snapshot)
    reused = pipeline.update(again, extract_frontiers(again), robot)
    assert reused.timings_ms["distance_transforms"] == 0.0
    fresh_pipeline = DirectionPipeline(DriveNavConfig())
    fresh_pipeline.update(snapshot, frontiers, (4.0, 4.0))
    fresh = fresh_pipeline.update(again, extract_frontiers(again), robot)
    _same_result(reused, fresh)


def test_a_changed_obstacle_rebuilds_the_speed_field() -> None:
    snapshot, frontiers = t_junction()
    pipeline = DirectionPipeline(DriveNavConfig())
    first = pipeline.update(snapshot, frontiers, (4.0, 4.0))
    obstacle = snapshot.obstacle.copy()
    obstacle[80, 75] = True  # one new obstacle cell inside the corridor
    changed = MapSnapshot(snapshot.grid, obstacle, snapshot.explored.copy(), snapshot.navigable.copy())
    second = pipeline.update(changed, frontiers, (4.0, 4.0))
    assert second.timings_ms["distance_transforms"] > 0.0
    fresh = DirectionPipeline(DriveNavConfig())
    fresh.update(snapshot, frontiers, (4.0, 4.0))
    _same_result(second, fresh.update(changed, frontiers, (4.0, 4.0)))
    assert first.directions  # the junction has directions at all


def test_frontier_cells_of_all_frontiers_at_once_are_each_frontiers_traversable_window_cells() -> None:
    snapshot, frontiers = t_junction()
    outside = np.array([[-3, 5], [0, 400], [2, 2]], dtype=np.int64)  # off the grid, off the window, untraversable
    extra = dataclasses.replace(frontiers[0], frontier_id=99, cells=np.vstack([frontiers[0].cells, outside]))
    field = build_speed_field(snapshot, frontiers, SpeedFieldConfig())
    every = [*frontiers, extra, dataclasses.replace(frontiers[0], frontier_id=100, cells=outside)]
    w = field.window
    for frontier, cells in zip(every, _frontier_cells(field, every), strict=True):
        local = frontier.cells - (w.r0, w.c0)
        local = local[w.grid.contains(local)]
        np.testing.assert_array_equal(cells, local[field.traversable[local[:, 0], local[:, 1]]])
    assert _frontier_cells(field, []) == []


def test_an_unchanged_map_robot_and_goal_reuse_the_solve() -> None:
    """Turning in place with nothing new in view runs no FMM; a new goal or position solves again."""
    snapshot, frontiers = t_junction()
    pipeline = DirectionPipeline(DriveNavConfig())
    pipeline.update(snapshot, frontiers, (4.0, 4.0))
    again = _copy_snapshot(snapshot)
    reused = pipeline.update(again, extract_frontiers(again), (4.0, 4.0))
    assert reused.timings_ms["fmm"] == 0.0 and reused.timings_ms["backtracking"] == 0.0
    fresh = DirectionPipeline(DriveNavConfig())
    fresh.update(snapshot, frontiers, (4.0, 4.0))
    _same_result(reused, fresh.update(again, extract_frontiers(again), (4.0, 4.0)))
    goal = (6.5, 4.0)
    planned = pipeline.update(again, extract_frontiers(again), (4.0, 4.0), goals=[goal])
    assert planned.timings_ms["fmm"] > 0.0
    expected = fresh.update(again, extract_frontiers(again), (4.0, 4.0), goals=[goal])
    _same_result(planned, expected)
    assert planned.goal_paths[0] is not None and expected.goal_paths[0] is not None
    np.testing.assert_array_equal(planned.goal_paths[0], expected.goal_paths[0])


@pytest.mark.parametrize("robot", [(4.0, 4.0), (4.0, 2.2), (6.0, 4.0)])
def test_each_paths_farthest_point_is_its_frontiers_member_farthest_from_the_robot(robot: tuple[float, float]) -> None:
    snapshot, frontiers = t_junction()
    result = DirectionPipeline(DriveNavConfig()).update(snapshot, frontiers, robot)
    by_id = {f.frontier_id: f for f in frontiers}
    assert result.paths
    for frontier_id, path in result.paths.items():
        points = by_id[frontier_id].points
        far = points[int(np.argmax(((points - robot) ** 2).sum(axis=1)))]
        assert path.farthest_point == (float(far[0]), float(far[1]))
        assert path.path.flags.c_contiguous and np.array_equal(path.path[0], robot)


def test_renumbered_frontiers_on_an_unchanged_map_are_solved_again() -> None:
    """The reused solve carries frontier ids: the same cells under other ids give paths under the new ids."""
    snapshot, frontiers = t_junction()
    pipeline = DirectionPipeline(DriveNavConfig())
    first = pipeline.update(snapshot, frontiers, (4.0, 4.0))
    renumbered = [dataclasses.replace(f, frontier_id=f.frontier_id + 10) for f in frontiers]
    second = pipeline.update(snapshot, renumbered, (4.0, 4.0))
    assert second.timings_ms["fmm"] > 0.0
    assert set(second.paths) == {k + 10 for k in first.paths}
