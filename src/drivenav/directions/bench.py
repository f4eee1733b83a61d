"""Benchmark of the directions core on a synthetic 480 x 480 house map (5 cm cells), partly and mostly explored.

The house (24 m x 24 m) has a cross of corridors and eight furnished rooms. In the main case the explored region is
what a 5 m range sensor saw from a handful of viewpoints along the corridors, so frontiers appear at range limits,
at doorways and in shadows; in the ``mostly_explored`` case the sensor also looked from inside every room, so the
solve covers most of the house and few frontiers are left. Each timed run recomputes everything from the map (no
caching across runs). The same grid and speed field are also solved with scikit-fmm's ``travel_time`` (the solver
of SemExp, L3MVN and home-robot), which solves the whole reachable region: ``ratio_vs_skfmm`` is our FMM stage's
median over its median. ``fmm_cells`` / ``skfmm_cells`` are the cells each solve settles and ``*_ns_per_cell`` their
cost per settled cell, so the ratio reads as the product of a work ratio and a per-cell cost ratio.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.directions.pipeline import TIMING_KEYS, DirectionPipeline, arrival_times, source_cell
from drivenav.directions.speed import build_speed_field
from drivenav.directions.synthetic import extract_frontiers, make_snapshot, rect
from drivenav.directions.types import DirectionResult
from drivenav.jsonstream import JsonObject
from drivenav.mapping.types import Frontier, MapSnapshot
from drivenav.paper import DriveNavConfig

RESOLUTION = 0.05
SIZE = 480
SENSOR_RANGE = 5.0
N_RAYS = 1440
VIEWPOINTS = (
    (4.0, 11.8),
    (8.0, 11.8),
    (11.8, 11.8),
    (11.8, 8.5),
    (6.5, 15.0),
    (11.8, 14.5),
    (15.5, 11.8),
    (19.5, 11.8),
    (16.0, 15.5),
    (8.5, 8.0),
)
ROOM_VIEWPOINTS = (
    (3.5, 6.0),
    (8.5, 5.0),
    (14.5, 8.0),
    (20.5, 6.0),
    (3.5, 18.0),
    (8.5, 20.0),
    (15.0, 19.5),
    (21.0, 19.0),
)
ROBOT_XY = (11.8, 11.8)
MIN_FRONTIER_CELLS = 8
WALL = 0.1


def house_free_space() -> NDArray[np.bool_]:
    """Ground-truth free space of the synthetic house (True = free)."""
    free = np.zeros((SIZE, SIZE), np.bool_)
    rect(free, 1.0, 1.0, 23.0, 23.0)
    walls = np.zeros_like(free)
    for y in (11.0, 12.6):  # horizontal corridor walls
        rect(walls, 1.0, y - WALL / 2, 23.0, y + WALL / 2)
    for x in (11.0, 12.6):  # vertical corridor walls
        rect(walls, x - WALL / 2, 1.0, x + WALL / 2, 23.0)
    for x in (6.0, 17.6):  # walls splitting each quadrant into two rooms
        rect(walls, x - WALL / 2, 1.0, x + WALL / 2, 11.0)
        rect(walls, x - WALL / 2, 12.6, x + WALL / 2, 23.0)
    free &= ~walls
    rect(free, 10.9, 11.0, 12.7, 12.6)  # corridor crossing
    rect(free, 11.0, 10.9, 12.6, 12.7)
    for x0 in (3.0, 8.0, 14.0, 19.5):  # doors from the horizontal corridor into every room
        rect(free, x0, 10.9, x0 + 0.9, 11.1)
        rect(free, x0, 12.5, x0 + 0.9, 12.7)
    rect(free, 5.9, 15.0, 6.1, 15.9)  # a door between two rooms
    furniture = ((2.0, 14.0, 3.2, 15.0), (7.5, 17.0, 9.5, 18.0), (14.0, 5.0, 15.5, 6.0), (19.0, 15.0, 20.5, 17.5))
    for box in furniture:
        obstacle = np.zeros_like(free)
        rect(obstacle, *box)
        free &= ~obstacle
    return free


def visible_cells(free: NDArray[np.bool_], viewpoint: tuple[float, float]) -> NDArray[np.bool_]:
    """Cells seen from ``viewpoint`` by a 360-degree range sensor: free cells up to the first wall, and it."""
    angles = np.linspace(0.0, 2.0 * math.pi, N_RAYS, endpoint=False)
    steps = np.arange(0.0, SENSOR_RANGE, RESOLUTION / 2)
    xs = viewpoint[0] + np.cos(angles)[:, None] * steps[None, :]
    ys = viewpoint[1] + np.sin(angles)[:, None] * steps[None, :]
    rows = np.clip((ys / RESOLUTION).astype(np.int64), 0, SIZE - 1)
    cols = np.clip((xs / RESOLUTION).astype(np.int64), 0, SIZE - 1)
    blocked = ~free[rows, cols]
    first_hit = np.where(blocked.any(axis=1), blocked.argmax(axis=1), steps.size - 1)
    keep = np.arange(steps.size)[None, :] <= first_hit[:, None]
    seen = np.zeros_like(free)
    seen[rows[keep], cols[keep]] = True
    return seen


def bench_scene(mostly_explored: bool = False) -> tuple[MapSnapshot, list[Frontier], tuple[float, float]]:
    """The benchmark's snapshot, frontiers (at least ``MIN_FRONTIER_CELLS`` cells each) and robot position; with
    ``mostly_explored``, the sensor also looked from inside every room."""
    free = house_free_space()
    explored = np.zeros_like(free)
    for viewpoint in VIEWPOINTS + (ROOM_VIEWPOINTS if mostly_explored else ()):
        explored |= visible_cells(free, viewpoint)
    snapshot = make_snapshot(free, explored, RESOLUTION, inflation=0.15)
    return snapshot, extract_frontiers(snapshot, MIN_FRONTIER_CELLS), ROBOT_XY


def _time_pipeline(
    pipeline: DirectionPipeline, scene: tuple[MapSnapshot, list[Frontier], tuple[float, float]], repeats: int
) -> tuple[DirectionResult, list[float], list[dict[str, float]]]:
    """The last result, the wall time and the stage timings of ``repeats`` full updates (after a warm-up)."""
    snapshot, frontiers, robot = scene
    result = pipeline.update(snapshot, frontiers, robot)  # warm-up: compiles or loads the numba kernels
    runs: list[dict[str, float]] = []
    wall: list[float] = []
    for _ in range(repeats):
        pipeline.reset()
        start = time.perf_counter()
        result = pipeline.update(snapshot, frontiers, robot)
        wall.append((time.perf_counter() - start) * 1e3)
        runs.append(result.timings_ms)
    return result, wall, runs


def _stage_medians(runs: list[dict[str, float]]) -> dict[str, float]:
    """The median ms of each stage over the timed runs."""
    return {key: float(np.median([r[key] for r in runs])) for key in TIMING_KEYS if key != "total"}


@dataclass(frozen=True)
class SolverCells:
    """The cells each solver settles on the main case: ``fmm`` by our early-stopping solve (finite ``T``), ``skfmm``
    by scikit-fmm, which solves the whole region it can reach from the robot."""

    fmm: int
    skfmm: int


def skfmm_reference(
    scene: tuple[MapSnapshot, list[Frontier], tuple[float, float]], config: DriveNavConfig, repeats: int
) -> tuple[float, SolverCells]:
    """Median ms of scikit-fmm's ``travel_time`` from the robot's cell on the pipeline's own grid and speed field, and
    the cells both solvers settle there."""
    import skfmm

    snapshot, frontiers, robot = scene
    field = build_speed_field(snapshot, frontiers, config.speed)
    source = source_cell(field, robot, config.directions.source_snap_radius)
    if source is None:
        raise ValueError("the benchmark's robot has no traversable cell")
    phi = np.ones(field.speed.shape)
    phi[source] = -1.0
    blocked = field.speed <= 0.0
    phi_masked = np.ma.MaskedArray(phi, blocked)
    speed_masked = np.ma.MaskedArray(np.where(blocked, 1.0, field.speed), blocked)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        reference = skfmm.travel_time(phi_masked, speed_masked, dx=field.window.grid.resolution)
        times.append((time.perf_counter() - start) * 1e3)
    ours = arrival_times(field, frontiers, robot, config.directions)
    cells = SolverCells(int(np.isfinite(ours).sum()), int(np.ma.count(reference)))
    return float(np.median(times)), cells


def bench_directions(repeats: int = 50, config: DriveNavConfig | None = None) -> JsonObject:
    """Time :meth:`DirectionPipeline.update` (map -> labelled directions for all frontiers) on one core.

    Returns the map size, frontier and direction counts, the median total in ms and the median of each stage, the
    same for the ``mostly_explored`` map (its stages in its own ``breakdown_ms``), and scikit-fmm's time on the main
    case's grid and speed field, with the cells each solver settles and the time per settled cell (our FMM stage's
    median over its cells).
    """
    config = config or DriveNavConfig()
    scene = bench_scene()
    snapshot, frontiers, _ = scene
    result, wall, runs = _time_pipeline(DirectionPipeline(config), scene, repeats)
    breakdown = _stage_medians(runs)
    explored_scene = bench_scene(mostly_explored=True)
    explored_result, explored_wall, explored_runs = _time_pipeline(DirectionPipeline(config), explored_scene, repeats)
    reference, cells = skfmm_reference(scene, config, max(3, repeats // 5))
    return {
        "map_cells": int(snapshot.obstacle.size),
        "map_shape": [int(s) for s in snapshot.obstacle.shape],
        "resolution": RESOLUTION,
        "explored_cells": int(snapshot.explored.sum()),
        "frontiers": len(frontiers),
        "reachable_frontiers": len(result.paths),
        "directions": len(result.directions),
        "repeats": repeats,
        "median_ms": float(np.median(wall)),
        "min_ms": float(np.min(wall)),
        "breakdown_ms": breakdown,
        "skfmm_ms": reference,
        "ratio_vs_skfmm": breakdown["fmm"] / reference,
        "fmm_cells": cells.fmm,
        "skfmm_cells": cells.skfmm,
        "fmm_ns_per_cell": breakdown["fmm"] * 1e6 / max(cells.fmm, 1),
        "skfmm_ns_per_cell": reference * 1e6 / max(cells.skfmm, 1),
        "mostly_explored": {
            "explored_cells": int(explored_scene[0].explored.sum()),
            "frontiers": len(explored_scene[1]),
            "directions": len(explored_result.directions),
            "median_ms": float(np.median(explored_wall)),
            "breakdown_ms": _stage_medians(explored_runs),
        },
    }
