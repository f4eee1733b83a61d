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

import numpy as np
from numpy.typing import NDArray

from drivenav.config import DriveNavConfig
from drivenav.directions.bearings import Point, bearing_to, circle_crossing
from drivenav.directions.clustering import build_clusters
from drivenav.directions.fmm import travel_time
from drivenav.directions.paths import backtrack, backtrack_many
from drivenav.directions.speed import SpeedField, build_speed_field
from drivenav.directions.timing import elapsed_ms
from drivenav.directions.tracking import DirectionTracker
from drivenav.directions.types import DirectionResult, FrontierPath
from drivenav.mapping.types import Frontier, MapSnapshot

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


class DirectionPipeline:
    """Stateful per-episode entry point: :meth:`update` once per mapping step, :meth:`reset` per episode."""

    def __init__(self, config: DriveNavConfig) -> None:
        self._config = config
        self._tracker = DirectionTracker(config.directions)
        self._last_field: tuple[MapSnapshot, tuple[Frontier, ...], SpeedField] | None = None

    def reset(self) -> None:
        self._tracker.reset()
        self._last_field = None

    def _speed_field(self, snapshot: MapSnapshot, frontiers: Sequence[Frontier]) -> SpeedField:
        """The speed field, rebuilt only when what it is a function of changed: the grid, the obstacle and navigable
        maps and the frontier cells (not the explored map, not the robot). A re-plan within one step (a new goal at
        a decision) and a step that changed none of them (about a fifth of the steps: turning in place towards
        known space) reuse the last one, reporting no distance-transform or skeleton time."""
        last = self._last_field
        if last is not None and _same_field_inputs(last[0], last[1], snapshot, frontiers):
            return dataclasses.replace(last[2], timings_ms=dict.fromkeys(last[2].timings_ms, 0.0))
        field = build_speed_field(snapshot, frontiers, self._config.speed)
        self._last_field = (snapshot, tuple(frontiers), field)
        return field

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
        :attr:`DirectionResult.goal_paths`.
        """
        t_start = time.perf_counter()
        robot_xy = (float(robot_xy[0]), float(robot_xy[1]))
        timings = dict.fromkeys(TIMING_KEYS, 0.0)
        field = self._speed_field(snapshot, frontiers)
        timings.update(field.timings_ms)

        t = time.perf_counter()
        cfg = self._config.directions
        source = source_cell(field, robot_xy, cfg.source_snap_radius)
        cells = _frontier_cells(field, frontiers)
        goal_cells = [nearest_traversable(field, goal, cfg.goal_snap_radius) for goal in goals]
        T = self._solve(field, source, cells, [g for g in goal_cells if g is not None])
        timings["fmm"] = elapsed_ms(t)

        t = time.perf_counter()
        found = self._frontier_paths(field, T, source, frontiers, cells, robot_xy)
        paths = [p for p in found if p is not None]
        unreachable = [f.frontier_id for f, p in zip(frontiers, found, strict=True) if p is None]
        robot = np.asarray(robot_xy, dtype=np.float64)
        goal_paths = tuple(_goal_path(field, T, source, cell, robot) for cell in goal_cells)
        timings["backtracking"] = elapsed_ms(t)

        t = time.perf_counter()
        by_id = {f.frontier_id: f for f in frontiers}
        clusters = build_clusters(paths, by_id, robot_xy, self._config.directions.cluster_span)
        timings["clustering"] = elapsed_ms(t)

        t = time.perf_counter()
        directions = self._tracker.update(clusters)
        timings["tracking"] = elapsed_ms(t)
        timings["total"] = elapsed_ms(t_start)
        paths_by_id = {p.frontier_id: p for p in paths}
        update = self._tracker.last_update
        return DirectionResult(directions, paths_by_id, tuple(unreachable), timings, goal_paths, update)

    def _solve(
        self,
        field: SpeedField,
        source: tuple[int, int] | None,
        cells: Sequence[NDArray[np.int64]],
        goal_cells: Sequence[tuple[int, int]],
    ) -> NDArray[np.float64]:
        """One FMM solve from ``source`` that stops shortly after every frontier with cells and every goal
        cell is reached."""
        targets = [c for c in cells if c.size] + [np.array([g], dtype=np.int64) for g in goal_cells]
        if source is None or not targets:
            return np.full(field.speed.shape, np.inf)
        labels = _target_labels(field.speed.shape, targets)
        res = field.window.grid.resolution
        slowest = float(field.speed[field.traversable].min())
        return travel_time(
            field.speed,
            res,
            np.array([source], dtype=np.int64),
            np.zeros(1),
            target_label=labels,
            margin=self._config.directions.margin_cells * res / slowest,
        )

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
        walks = backtrack_many(T, field.traversable, starts, source)
        found: list[FrontierPath | None] = [None] * len(frontiers)
        for i, start, rc in zip(reached, starts, walks, strict=True):
            found[i] = self._frontier_path(field, frontiers[i], rc, float(T[start[0], start[1]]), robot_xy)
        return found

    def _frontier_path(
        self, field: SpeedField, frontier: Frontier, rc: NDArray[np.float64], time: float, robot_xy: Sequence[float]
    ) -> FrontierPath:
        """The frontier's path (backtracked window points ``rc``, arrival ``time`` at its start) and bearing."""
        robot = np.asarray(robot_xy[:2], dtype=np.float64)
        path = _world_path(field, rc, robot)
        cfg = self._config.directions
        waypoint = (float(frontier.waypoint[0]), float(frontier.waypoint[1]))
        point = circle_crossing(path, robot, cfg.bearing_radius) if cfg.path_bearings else waypoint
        if _same_point(point, robot):  # degenerate: the frontier is at the robot; use its waypoint
            point = waypoint
        far = frontier.points[int(np.argmax(((frontier.points - robot) ** 2).sum(axis=1)))]
        target = path[-1]
        return FrontierPath(
            frontier.frontier_id,
            (float(target[0]), float(target[1])),
            time,
            path,
            point,
            bearing_to(robot, point),
            (float(far[0]), float(far[1])),
        )


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


def _world_path(field: SpeedField, rc: NDArray[np.float64], robot: NDArray[np.float64]) -> NDArray[np.float64]:
    """Backtracked window ``(row, col)`` points (target to source) as a world ``(x, y)`` polyline from the
    robot to the target; the robot itself is prepended unless it stands on the source cell's centre."""
    grid = field.window.grid
    world = (rc[::-1, ::-1] + 0.5) * grid.resolution + grid.origin
    return world if _same_point(world[0], robot) else np.vstack([robot, world])


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
    return all(x is y or np.array_equal(x, y) for x, y in (*maps, *cells))


def _same_point(a: Point, b: Point) -> bool:
    return bool(abs(a[0] - b[0]) < 1e-9 and abs(a[1] - b[1]) < 1e-9)
