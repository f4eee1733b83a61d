"""The embedded world served as a robot (``drivenav robot serve-sim``): sensor source, motion executor and episode
world in one, with a simulated 2-D LiDAR.

It knows the episodes, so RESET places it at an episode's start and BYE reports the episode's Habitat metrics: the
same episodes run directly and through the protocol give the same actions and metrics (the parity test). Its
frames carry the ground-truth instance ids (``semantic``), which only a simulated robot has, and its poses the height
of the floor or stairs under it (in a building of several storeys), as a 3-D odometry would.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivenav.envs.base import EpisodeMeasures
from drivenav.envs.embedded.building import floor_plan
from drivenav.envs.embedded.env import EmbeddedEnv
from drivenav.envs.embedded.scene import Scene
from drivenav.episode import Episode
from drivenav.grid import GridSpec
from drivenav.robot.parts import MotionResult, SensorFrame
from drivenav.types import SEMANTIC, Action, Observation, Pose
from drivenav.wire.payloads import check_claimed_episode
from drivenav.wire.protocol import JSON, RobotInfo


@dataclass(frozen=True)
class SimulatedLidar:
    """A planar LiDAR at ``height`` metres: ``beams`` rays over 360 degrees, returns up to ``max_range``."""

    height: float = 0.5
    beams: int = 720
    max_range: float = 10.0

    def scan(self, blocked: NDArray[np.bool_], grid: GridSpec, pose: Pose) -> NDArray[np.float32]:
        """(N, 3) base-frame points where the rays from ``pose`` first meet a ``blocked`` cell (no point for a ray
        that meets none within range)."""
        bearings = np.linspace(-math.pi, math.pi, self.beams, endpoint=False)
        steps = np.arange(1, math.ceil(self.max_range / (0.5 * grid.resolution)) + 1) * 0.5 * grid.resolution
        angles = pose.yaw + bearings
        xs = pose.x + np.cos(angles)[:, None] * steps[None, :]
        ys = pose.y + np.sin(angles)[:, None] * steps[None, :]
        cells = grid.world_to_cell(np.stack([xs, ys], axis=-1))
        rows, cols = cells[..., 0], cells[..., 1]
        inside = (rows >= 0) & (rows < grid.shape[0]) & (cols >= 0) & (cols < grid.shape[1])
        hit = np.zeros(rows.shape, dtype=np.bool_)
        hit[inside] = blocked[rows[inside], cols[inside]]
        hit |= ~inside  # the map's edge is a wall
        any_hit = hit.any(axis=1)
        first = np.argmax(hit, axis=1)
        ranges = steps[first][any_hit]
        b = bearings[any_hit]
        points = np.stack([ranges * np.cos(b), ranges * np.sin(b), np.full(b.shape, self.height)], axis=1)
        return points.astype(np.float32)


class SimulatedRobot:
    """An :class:`EmbeddedEnv` as sensor source, motion executor and episode world of a robot server."""

    def __init__(self, env: EmbeddedEnv, episodes: Sequence[Episode], lidar: SimulatedLidar | None = None) -> None:
        self._env = env
        self._episodes = {e.episode_id: e for e in episodes}
        self._lidar = lidar
        self._observation: Observation | None = None
        self._blocked: tuple[Scene, NDArray[np.bool_]] | None = None  # a floor plan and its obstacles

    def info(self) -> RobotInfo:
        """What this robot says of itself at HELLO: the world's sensor and body, ground-truth labels."""
        return RobotInfo.from_sim(self._env.config, provides=(SEMANTIC,), lidar=self._lidar is not None)

    # -- EpisodeWorld -------------------------------------------------------------------------------------------------
    def start(self, episode_id: str, body: Mapping[str, JSON]) -> None:
        episode = self._episodes[episode_id]
        check_claimed_episode(episode, body)
        self._observation = self._env.reset(episode)
        self._blocked = None

    def measures(self) -> EpisodeMeasures:
        return self._env.measures()

    def labels(self) -> Mapping[int, str]:
        return self._env.ground_truth(frozenset({SEMANTIC})).labels or {}

    # -- SensorSource -------------------------------------------------------------------------------------------------
    def read(self) -> SensorFrame:
        observation = self._observation
        if observation is None:
            raise RuntimeError("the simulated robot has no episode: RESET with an episode id first")
        pose = self._env.world_pose()
        return SensorFrame(
            rgb=observation.rgb,
            depth=observation.depth,
            pose=pose,
            intrinsics=observation.intrinsics,
            stamp=0.1 * observation.step,
            scan=self._scan(pose),
            semantic=observation.semantic,
        )

    def _scan(self, pose: Pose) -> NDArray[np.float32] | None:
        if self._lidar is None:
            return None
        plan = floor_plan(self._env.scene, pose.z)
        if self._blocked is None or self._blocked[0] is not plan:
            self._blocked = (plan, plan.obstacle_grid(self._env.config.agent_height))
        return self._lidar.scan(self._blocked[1], plan.grid, pose)

    def close(self) -> None:
        self._env.close()

    # -- MotionExecutor -----------------------------------------------------------------------------------------------
    def execute(self, action: Action) -> MotionResult:
        self._observation = self._env.step(action)
        return MotionResult(self._observation.collided)

    def stop(self) -> None:
        """The simulated robot never keeps moving between steps."""
