"""Timing of the mapping update and of frontier extraction on synthetic frames of a small apartment."""

from __future__ import annotations

import math
import time
from typing import TypedDict

import numpy as np

from drivenav.mapping.config import MappingConfig
from drivenav.mapping.occupancy import OccupancyMapper
from drivenav.mapping.synthetic import Box3, BoxWorld, room, wall
from drivenav.types import CameraIntrinsics, Pose, SimConfig


class BenchResult(TypedDict):
    """Milliseconds are medians / 90th percentiles over every frame of every repeat (after a warm-up)."""

    median_ms: float
    p90_ms: float
    frontier_ms: float
    frontier_p90_ms: float
    frames: int
    repeats: int
    width: int
    height: int
    pixel_stride: int
    map_shape: tuple[int, int]
    frontiers: int


def apartment() -> BoxWorld:
    """A 8 m x 6 m living room with furniture, a door east into a 6 m x 8 m second room."""
    furniture = [
        Box3((1.0, 2.2), (1.0, 1.8), (0.0, 0.75)),  # table
        Box3((-3.5, -1.5), (-2.8, -2.0), (0.0, 0.45)),  # sofa
        Box3((2.8, 3.1), (-1.6, -1.3), (0.0, 2.5)),  # pillar
    ]
    second = [
        wall(4, -4, 10, -4),
        wall(4, 4, 10, 4),
        wall(10, -4, 10, 4),
        wall(4, -4, 4, -3),
        wall(4, 3, 4, 4),
    ]
    return BoxWorld(tuple(room(-4, -3, 4, 3, door_east=(-0.6, 0.6)) + second + furniture))


def trajectory(frames: int) -> list[Pose]:
    """A 360-degree scan at the origin (12 turns of 30 degrees), then a walk east through the door."""
    poses = [Pose(0.0, 0.0, k * math.pi / 6.0) for k in range(12)]
    for k in range(max(frames - 12, 0)):
        poses.append(Pose(0.25 * (k + 1), 0.15 * math.sin(k / 3.0), 0.3 * math.sin(k / 2.0)))
    return poses[:frames]


def bench_mapping(
    frames: int = 24,
    repeats: int = 5,
    width: int = 640,
    height: int = 480,
    config: MappingConfig | None = None,
) -> BenchResult:
    """Map ``frames`` synthetic depth frames ``repeats`` times (fresh mapper each time) and time each step.

    Per step the update is timed, then the first :meth:`OccupancyMapper.frontiers` call after it (derivation
    of the explored / navigable components plus frontier extraction), as an agent would call them.
    """
    sim = SimConfig(width=width, height=height)
    cfg = config if config is not None else MappingConfig.from_sim(sim)
    intrinsics = CameraIntrinsics.from_hfov(width, height, sim.hfov_deg)
    world = apartment()
    poses = trajectory(frames)
    depths = [world.render(p, intrinsics, cfg.camera_height, (cfg.min_depth, cfg.max_depth)) for p in poses]
    update_ms: list[float] = []
    frontier_ms: list[float] = []
    mapper = OccupancyMapper(cfg)
    for repeat in range(repeats + 1):
        mapper.reset()
        for depth, pose in zip(depths, poses, strict=True):
            start = time.perf_counter()
            mapper.update(depth, intrinsics, pose)
            middle = time.perf_counter()
            found = mapper.frontiers()
            end = time.perf_counter()
            if repeat > 0:  # repeat 0 warms up the compiled kernels
                update_ms.append((middle - start) * 1e3)
                frontier_ms.append((end - middle) * 1e3)
    return BenchResult(
        median_ms=float(np.median(update_ms)),
        p90_ms=float(np.percentile(update_ms, 90)),
        frontier_ms=float(np.median(frontier_ms)),
        frontier_p90_ms=float(np.percentile(frontier_ms, 90)),
        frames=len(depths),
        repeats=repeats,
        width=width,
        height=height,
        pixel_stride=cfg.pixel_stride,
        map_shape=mapper.grid.shape,
        frontiers=len(found),
    )
