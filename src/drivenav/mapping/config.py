"""Settings of the occupancy mapper (paper Sec. IV-A a: "a standard frontier-map pipeline")."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from drivenav.ranges import AREA, LENGTH, MAX_FRAME_SIDE, POSITIVE_LENGTH, Range, check_ranges, check_rule
from drivenav.types import SimConfig


@dataclass(frozen=True)
class MapTuning:
    """The mapper settings a user sets (the ``mapping`` section of the configuration); the rest of
    :class:`MappingConfig` follows from the sensor and body (:meth:`MappingConfig.from_sim`).

    ``fuse_lidar``: when a robot sends LiDAR occupancy (:attr:`~drivenav.types.Observation.occupancy`), fuse it
    into the obstacle and explored maps (paper Sec. V-E: on the real robot LiDAR and IMU give a 2-D occupancy grid
    restricted to the camera's forward 79 deg); simulation worlds send none, so the default is depth only.
    """

    min_obstacle_height: float = 0.15
    clip_epsilon: float = 0.01
    min_frontier_area: float = 1.5
    pocket_window: float = 2.0
    initial_size: float = 20.0
    growth_margin: float = 5.0
    max_size: float = 200.0
    pixel_stride: int = 2
    fuse_lidar: bool = False

    def __post_init__(self) -> None:
        ranges = {
            "min_obstacle_height": LENGTH,
            "clip_epsilon": LENGTH,
            "min_frontier_area": AREA,
            "pocket_window": POSITIVE_LENGTH,
            "initial_size": POSITIVE_LENGTH,
            "growth_margin": LENGTH,
            "max_size": POSITIVE_LENGTH,
            "pixel_stride": Range(1, MAX_FRAME_SIDE, integer=True, why="every k-th row and column of a frame"),
        }
        check_ranges(self, ranges)
        expected = "at least initial_size (the grid starts that large and only grows)"
        check_rule(self, "max_size", self.max_size >= self.initial_size, expected)


@dataclass(frozen=True)
class MappingConfig(MapTuning):
    """Geometry and thresholds of the obstacle / explored / navigable maps and of frontier filtering.

    Heights are measured above the floor. A depth point whose height lies in
    ``[min_obstacle_height, max_obstacle_height]`` is an obstacle; lower points are floor, higher points are
    ignored. The default band starts above floor clutter the agent can step over (rugs, thresholds; Habitat's
    navmesh climbs 0.2 m) and ends at the agent's height (0.88 m): structure above the agent does not block
    it.
    Depth readings within ``clip_epsilon`` of ``min_depth`` / ``max_depth`` are clip values, never obstacles.

    ``min_frontier_area`` (m^2, VLFM's 1.5) drops frontiers whose unexplored pocket is smaller; the pocket is
    measured inside a window ``pocket_window`` metres around the frontier (:mod:`drivenav.mapping.frontiers`).
    The grid starts ``initial_size`` metres square around the episode origin and grows by ``growth_margin``
    metres beyond what an observation needs whenever the sensor range would reach its edge, up to ``max_size``
    metres a side (frames from farther poses, e.g. after an odometry jump, are ignored).
    ``pixel_stride`` subsamples rows and columns of the depth image for the update. Obstacles are inflated by
    ``agent_radius + inflation_margin`` for the navigable map; :meth:`from_sim` sets a margin of one cell so that
    planned paths keep clear of what the world counts as blocked.
    """

    resolution: float = 0.05
    max_obstacle_height: float = 0.88
    min_depth: float = 0.5
    max_depth: float = 5.0
    camera_height: float = 0.88
    agent_radius: float = 0.18
    inflation_margin: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        ranges = {
            "resolution": POSITIVE_LENGTH,
            "max_obstacle_height": LENGTH,
            "min_depth": LENGTH,
            "max_depth": POSITIVE_LENGTH,
            "camera_height": LENGTH,
            "agent_radius": LENGTH,
            "inflation_margin": LENGTH,
        }
        check_ranges(self, ranges)
        check_rule(self, "min_depth", self.min_depth < self.max_depth, "less than max_depth")
        expected = "less than max_obstacle_height (the top of the obstacle band)"
        check_rule(self, "min_obstacle_height", self.min_obstacle_height < self.max_obstacle_height, expected)

    @staticmethod
    def from_sim(sim: SimConfig, tuning: MapTuning | None = None, **overrides: Any) -> MappingConfig:
        """The mapping settings matching a simulator set-up (depth range, camera height, agent, grid)."""
        base = MappingConfig(
            resolution=sim.grid_resolution,
            min_depth=sim.min_depth,
            max_depth=sim.max_depth,
            camera_height=sim.camera_height,
            agent_radius=sim.agent_radius,
            inflation_margin=sim.grid_resolution,
            max_obstacle_height=sim.agent_height,
        )
        return dataclasses.replace(base, **{**dataclasses.asdict(tuning or MapTuning()), **overrides})
