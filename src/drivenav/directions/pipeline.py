"""Map + frontiers -> labelled persistent directions, one call per mapping step (Sec. IV-A a-b).

One weighted FMM solve from the robot serves every frontier. Per frontier:

* the backtracked point is the frontier's reachable cell of least arrival time ``T`` (the natural end of the
  weighted path towards that frontier; it is also the first frontier cell the marching settles, which is what
  lets the solve stop early); frontiers none of whose cells is reachable are dropped;
* the "farthest frontier point" kept for the agent is the member cell farthest from the robot in Euclidean
  distance (cheap, and independent of where the marching stopped);
* the bearing theta_i goes from the robot to the first crossing of the path with the R_e circle, or to the
  frontier waypoint in the ``path_bearings=False`` ablation.

Goal paths (for the low-level planner that follows the selected direction's farthest frontier point or
approaches a detected object, Sec. IV): each goal point is snapped to the nearest traversable cell within
``goal_snap_radius``, marked as one more target of the same early-stopping solve, and backtracked like a
frontier, so following a goal costs no second FMM solve.

The robot's own cell seeds the marching (``T = 0``). If that cell is not traversable (the robot stands in the
inflation band), the nearest traversable cell within ``source_snap_radius`` seeds it instead and the path's first
segment runs from the robot to that cell's centre -- the only segment allowed to touch non-traversable cells.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.directions.bearings import Point, bearing_to, circle_crossing
from drivenav.directions.clustering import build_clusters
from drivenav.directions.fmm import travel_time
from drivenav.directions.paths import backtrack, backtrack_walks
from drivenav.directions.speed import SpeedField, SpeedFieldBuilder
from drivenav.directions.timing import elapsed_ms
from drivenav.directions.tracking import DirectionTracker
from drivenav.directions.types import Cluster, DirectionResult, FrontierPath
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import DirectionConfig, DriveNavConfig

TIMING_KEYS = ("distance_transforms", "skeleton", "fmm", "backtracking", "clustering", "tracking", "total")


def source_cell(field: SpeedField, robot_xy: Sequence[float], radius: float) -> tuple[int, int] | None:
    """The window cell that seeds the FMM: the robot's cell, else the nearest traversable one within
    ``radius`` (``DirectionConfig.source_snap_radius``); ``None`` if there is none."""
    return nearest_traversable(field, robot_xy, radius)


def nearest_traversable(field: SpeedField, xy: Point, radius: float) -> tuple[int, int] | None:
    """The window cell holding world point ``xy`` if traversable, else the nearest traversable cell whose
    centre distance from that cell is at most ``radius``; ``None`` if there is none."""
    grid = field.window.grid
    r, c = grid.cell_at(float(xy[0]), float(xy[1]))
    reach = int(np.ceil(radius / grid.resolution))
    r0, c0 = max(r - reach, 0), max(c - reach, 0)
    patch = field.traversable[r0 : max(r + reach + 1, 0), c0 : max(c + reach + 1, 0)]
    cells = np.argwhere(patch) + np.array([r0, c0])
    if cells.size == 0:
        return None
    d2 = ((cells - (r, c)) ** 2).sum(axis=1)
    best = int(np.argmin(d2))
    if d2[best] * grid.resolution**2 > radius**2:
        return None
    return int(cells[best, 0]), int(cells[best, 1])


def _frontier_cells(field: SpeedField, frontiers: Sequence[Frontier]) -> list[NDArray[np.int64]]:
    """Each frontier's traversable cells, in window coordinates (all frontiers masked in one pass)."""
    if not frontiers:
        return []
    w = field.window
    every = np.concatenate([f.cells for f in frontiers]) - (w.r0, w.c0)
    keep = w.grid.contains(every)
    keep[keep] = field.traversable[every[keep, 0], every[keep, 1]]
    kept_before = np.concatenate([[0], np.cumsum(keep)])
    ends = np.cumsum([len(f.cells) for f in frontiers])
    return np.split(np.asarray(every[keep], dtype=np.int64), kept_before[ends[:-1]])


@dataclass(frozen=True)
class _Solve:
    """What one FMM solve gave for a robot position and goals: the frontier paths by id, the unreachable
    frontiers, the goal paths and the clusters (tracking, which has state, runs every step)."""

    robot_xy: tuple[float, float]
    goals: tuple[tuple[float, float], ...]
    frontiers: tuple[Frontier, ...]
    paths: dict[int, FrontierPath]
    unreachable: tuple[int, ...]
    goal_paths: tuple[NDArray[np.float64] | None, ...]
    clusters: tuple[Cluster, ...]


class DirectionPipeline:
    """Stateful per-episode entry point: :meth:`update` once per mapping step, :meth:`reset` per episode."""

    def __init__(self, config: DriveNavConfig) -> None:
        self._config = config
        self._tracker = DirectionTracker(config.directions)
        self._builder = SpeedFieldBuilder(config.speed)
        self._last_field: tuple[MapSnapshot, tuple[Frontier, ...], SpeedField] | None = None
        self._last_solve: _Solve | None = None

    def reset(self) -> None:
        self._tracker.reset()
        self._builder.reset()
        self._last_field = None
        self._last_solve = None

    def _speed_field(self, snapshot: MapSnapshot, frontiers: Sequence[Frontier]) -> tuple[SpeedField, bool]:
        """The speed field and whether it is the last one: it is rebuilt only when what it is a function of changed:
        the grid, the obstacle and navigable maps and the frontier cells (not the explored map, not the robot). A
        re-plan within one step (a new goal at a decision) and a step that changed none of them (about a fifth of
        the steps: turning in place towards known space) reuse the last one, reporting no distance-transform or
        skeleton time."""
        last = self._last_field
        if last is not None and _same_field_inputs(last[0], last[1], snapshot, frontiers):
            return dataclasses.replace(last[2], timings_ms=dict.fromkeys(last[2].timings_ms, 0.0)), True
        field = self._builder.build(snapshot, frontiers)
        self._last_field = (snapshot, tuple(frontiers), field)
        return field, False

    def update(
        self,
        snapshot: MapSnapshot,
        frontiers: Sequence[Frontier],
        robot_xy: Sequence[float],
        goals: Sequence[Point] = (),
    ) -> DirectionResult:
        """Speed field, one FMM solve, paths, bearings, clustering and label tracking for this step.

        ``robot_xy`` is the robot's world position (extra items, e.g. a yaw, are ignored). ``goals`` are world
        points to plan to from the same solve (see the module docstring); their paths come back, in order, in
        :attr:`DirectionResult.goal_paths`. A step with the last step's speed field, robot position and goals (turning
        in place with nothing new in view) reuses the last solve, paths and clusters: only tracking runs.
        """
        t_start = time.perf_counter()
        robot_xy = (float(robot_xy[0]), float(robot_xy[1]))
        goal_points = tuple((float(g[0]), float(g[1])) for g in goals)
        timings = dict.fromkeys(TIMING_KEYS, 0.0)
        field, same_field = self._speed_field(snapshot, frontiers)
        timings.update(field.timings_ms)
        last = self._last_solve
        if same_field and last is not None and _same_solve_inputs(last, robot_xy, goal_points, frontiers):
            solve = last  # same field, robot, goals and frontiers: the same solve, paths and clusters (no FMM time)
        else:
            solve = self._solve_and_cluster(field, frontiers, robot_xy, goal_points, timings)
            self._last_solve = solve

        t = time.perf_counter()
        directions = self._tracker.update(solve.clusters)
        timings["tracking"] = elapsed_ms(t)
        timings["total"] = elapsed_ms(t_start)
        update = self._tracker.last_update
        return DirectionResult(directions, solve.paths, solve.unreachable, timings, solve.goal_paths, update)

    def travel_times(self, sources: Sequence[Point], targets: Sequence[Point]) -> NDArray[np.float64]:
        """Weighted-FMM arrival times (metres at unit speed) from each source point to each target point on the last
        :meth:`update`'s speed field: one early-stopping solve per source, points snapped as goals are
        (``goal_snap_radius``); ``inf`` where a point has no traversable cell near it or no path joins them (every
        entry before any update). The times between frontiers that ApexNav's TSP orders them by."""
        times = np.full((len(sources), len(targets)), np.inf)
        if self._last_field is None:
            return times
        field, cfg = self._last_field[2], self._config.directions
        cells = [nearest_traversable(field, target, cfg.goal_snap_radius) for target in targets]
        reached = [(k, cell) for k, cell in enumerate(cells) if cell is not None]
        for i, source in enumerate(sources):
            start = nearest_traversable(field, source, cfg.goal_snap_radius)
            if start is None or not reached:
                continue
            T = _solve(field, start, [], [cell for _, cell in reached], cfg.margin_cells)
            for k, cell in reached:
                times[i, k] = T[cell]
        return times

    def _solve_and_cluster(
        self,
        field: SpeedField,
        frontiers: Sequence[Frontier],
        robot_xy: tuple[float, float],
        goals: tuple[tuple[float, float], ...],
        timings: dict[str, float],
    ) -> _Solve:
        """The FMM solve, the frontier and goal paths and the clusters of one step; stage times go to ``timings``."""
        t = time.perf_counter()
        cfg = self._config.directions
        source = source_cell(field, robot_xy, cfg.source_snap_radius)
        cells = _frontier_cells(field, frontiers)
        goal_cells = [nearest_traversable(field, goal, cfg.goal_snap_radius) for goal in goals]
        T = _solve(field, source, cells, [g for g in goal_cells if g is not None], cfg.margin_cells)
        timings["fmm"] = elapsed_ms(t)

        t = time.perf_counter()
        found = self._frontier_paths(field, T, source, frontiers, cells, robot_xy)
        paths = [p for p in found if p is not None]
        unreachable = tuple(f.frontier_id for f, p in zip(frontiers, found, strict=True) if p is None)
        robot = np.asarray(robot_xy, dtype=np.float64)
        goal_paths = tuple(_goal_path(field, T, source, cell, robot) for cell in goal_cells)
        timings["backtracking"] = elapsed_ms(t)

        t = time.perf_counter()
        by_id = {f.frontier_id: f for f in frontiers}
        clusters = build_clusters(paths, by_id, robot_xy, cfg.cluster_span)
        timings["clustering"] = elapsed_ms(t)
        paths_by_id = {p.frontier_id: p for p in paths}
        return _Solve(robot_xy, goals, tuple(frontiers), paths_by_id, unreachable, goal_paths, tuple(clusters))

    def _frontier_paths(
        self,
        field: SpeedField,
        T: NDArray[np.float64],
        source: tuple[int, int] | None,
        frontiers: Sequence[Frontier],
        cells: Sequence[NDArray[np.int64]],
        robot_xy: Sequence[float],
    ) -> list[FrontierPath | None]:
        """Per frontier, the path backtracked from its least-time cell and its bearing (all walks in one call);
        ``None`` for a frontier none of whose cells is reachable."""
        reached: list[int] = []
        least: list[NDArray[np.int64]] = []
        for i, own in enumerate(cells):
            if own.size == 0:
                continue
            times = T[own[:, 0], own[:, 1]]
            k = int(np.argmin(times))
            if np.isfinite(times[k]):
                reached.append(i)
                least.append(own[k])
        if source is None or not reached:
            return [None] * len(frontiers)
        starts = np.array(least, dtype=np.int64)
        rc, offsets = backtrack_walks(T, field.traversable, starts, source)
        world = _to_world(field, rc)
        robot = np.asarray(robot_xy[:2], dtype=np.float64)
        far = _farthest_points([frontiers[i].points for i in reached], robot)
        found: list[FrontierPath | None] = [None] * len(frontiers)
        for n, (i, start) in enumerate(zip(reached, starts, strict=True)):
            path = _from_robot(world[offsets[n] : offsets[n + 1]][::-1], robot)
            found[i] = self._frontier_path(frontiers[i], path, float(T[start[0], start[1]]), robot, far[n])
        return found

    def _frontier_path(
        self,
        frontier: Frontier,
        path: NDArray[np.float64],
        time: float,
        robot: NDArray[np.float64],
        farthest: tuple[float, float],
    ) -> FrontierPath:
        """The frontier's path (world polyline from the robot, arrival ``time`` at its end) and bearing."""
        cfg = self._config.directions
        waypoint = (float(frontier.waypoint[0]), float(frontier.waypoint[1]))
        point = circle_crossing(path, robot, cfg.bearing_radius) if cfg.path_bearings else waypoint
        if _same_point(point, robot):  # degenerate: the frontier is at the robot; use its waypoint
            point = waypoint
        target = path[-1]
        return FrontierPath(
            frontier.frontier_id,
            (float(target[0]), float(target[1])),
            time,
            path,
            point,
            bearing_to(robot, point),
            farthest,
        )


def _solve(
    field: SpeedField,
    source: tuple[int, int] | None,
    cells: Sequence[NDArray[np.int64]],
    goal_cells: Sequence[tuple[int, int]],
    margin_cells: float,
) -> NDArray[np.float64]:
    """One FMM solve from ``source`` that stops shortly after every frontier with cells and every goal
    cell is reached (``margin_cells``: ``DirectionConfig.margin_cells``)."""
    targets = [c for c in cells if c.size] + [np.array([g], dtype=np.int64) for g in goal_cells]
    if source is None or not targets:
        return np.full(field.speed.shape, np.inf)
    labels = _target_labels(field.speed.shape, targets)
    return travel_time(
        field.speed,
        field.window.grid.resolution,
        np.array([source], dtype=np.int64),
        np.zeros(1),
        target_label=labels,
        margin_cells=margin_cells,
    )


def arrival_times(
    field: SpeedField, frontiers: Sequence[Frontier], robot_xy: Sequence[float], config: DirectionConfig
) -> NDArray[np.float64]:
    """The arrival times ``T`` of :meth:`DirectionPipeline.update`'s solve for these frontiers and no goals: ``inf``
    on the cells the early-stopping marching did not settle (``drivenav bench directions`` counts them)."""
    source = source_cell(field, robot_xy, config.source_snap_radius)
    return _solve(field, source, _frontier_cells(field, frontiers), [], config.margin_cells)


def _target_labels(shape: tuple[int, int], targets: Sequence[NDArray[np.int64]]) -> NDArray[np.int32]:
    """Early-termination labels: the cells of target set ``k`` get label ``k``, later sets overwriting earlier
    ones. The marching waits for a cell of every label, so labels left without cells (a frontier all of whose
    cells are goal cells) are dropped and the rest renumbered ``0..L-1``."""
    labels = np.full(shape, -1, np.int32)
    for k, own in enumerate(targets):
        labels[own[:, 0], own[:, 1]] = k
    every = np.concatenate(targets)
    present = np.zeros(len(targets), np.bool_)
    present[labels[every[:, 0], every[:, 1]]] = True
    if not present.all():
        renumber = np.cumsum(present, dtype=np.int32) - 1
        labels[every[:, 0], every[:, 1]] = renumber[labels[every[:, 0], every[:, 1]]]
    return labels


def _to_world(field: SpeedField, rc: NDArray[np.float64]) -> NDArray[np.float64]:
    """Continuous window ``(row, col)`` points (cell centres at integers) as world ``(x, y)`` points."""
    grid = field.window.grid
    return np.asarray((rc[:, ::-1] + 0.5) * grid.resolution + grid.origin, dtype=np.float64)


def _from_robot(world: NDArray[np.float64], robot: NDArray[np.float64]) -> NDArray[np.float64]:
    """A walk's world points, source first, as a polyline from the robot (a new array): the robot is prepended
    unless it stands on the source cell's centre."""
    return np.ascontiguousarray(world) if _same_point(world[0], robot) else np.concatenate((robot[None], world))


def _world_path(field: SpeedField, rc: NDArray[np.float64], robot: NDArray[np.float64]) -> NDArray[np.float64]:
    """Backtracked window ``(row, col)`` points (target to source) as a world ``(x, y)`` polyline from the
    robot to the target."""
    return _from_robot(_to_world(field, rc)[::-1], robot)


def _farthest_points(points: Sequence[NDArray[np.float64]], robot: NDArray[np.float64]) -> list[tuple[float, float]]:
    """Per point set, its point farthest from ``robot`` (the first of equals), all sets in one pass."""
    every = np.concatenate(points)
    d2 = np.add.reduce((every - robot) ** 2, axis=1)
    bounds = np.cumsum([0] + [len(p) for p in points])
    most = np.maximum.reduceat(d2, bounds[:-1])
    hits = np.flatnonzero(d2 == np.repeat(most, np.diff(bounds)))
    first = hits[np.searchsorted(hits, bounds[:-1])]
    return [(float(every[k, 0]), float(every[k, 1])) for k in first]


def _goal_path(
    field: SpeedField,
    T: NDArray[np.float64],
    source: tuple[int, int] | None,
    cell: tuple[int, int] | None,
    robot: NDArray[np.float64],
) -> NDArray[np.float64] | None:
    """The path from the robot to a snapped goal cell (ending at its centre); ``None`` if unreachable."""
    if source is None or cell is None or not np.isfinite(T[cell]):
        return None
    return _world_path(field, backtrack(T, field.traversable, cell, source), robot)


def _same_field_inputs(
    snapshot_a: MapSnapshot, frontiers_a: Sequence[Frontier], snapshot_b: MapSnapshot, frontiers_b: Sequence[Frontier]
) -> bool:
    """Whether two maps with their frontiers give the same speed field (see ``DirectionPipeline._speed_field``)."""
    if snapshot_a.grid != snapshot_b.grid or len(frontiers_a) != len(frontiers_b):
        return False
    maps = ((snapshot_a.obstacle, snapshot_b.obstacle), (snapshot_a.navigable, snapshot_b.navigable))
    cells = ((a.cells, b.cells) for a, b in zip(frontiers_a, frontiers_b, strict=True))
    return all(_same_array(x, y) for x, y in (*maps, *cells))


def _same_solve_inputs(
    last: _Solve, robot_xy: tuple[float, float], goals: tuple[tuple[float, float], ...], frontiers: Sequence[Frontier]
) -> bool:
    """Whether a step on the last step's speed field gives the last solve: the same robot position and goals, and
    frontiers with the same ids, waypoints and points (what the paths and clusters carry besides the field)."""
    if last.robot_xy != robot_xy or last.goals != goals or len(last.frontiers) != len(frontiers):
        return False
    return all(
        a.frontier_id == b.frontier_id and a.waypoint == b.waypoint and _same_array(a.points, b.points)
        for a, b in zip(last.frontiers, frontiers, strict=True)
    )


def _same_array(a: NDArray[np.generic], b: NDArray[np.generic]) -> bool:
    """The same array object, or equal shapes and contents."""
    return a is b or np.array_equal(a, b)


def _same_point(a: Point, b: Point) -> bool:
    return bool(abs(a[0] - b[0]) < 1e-9 and abs(a[1] - b[1]) < 1e-9)
