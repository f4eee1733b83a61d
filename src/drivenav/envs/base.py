"""The environment interface: observations, actions, and the simulator settings (Habitat ObjectNav defaults).

Frames. The *world* frame of a scene is the 2-D map frame (x east, y north, metres; yaw counter-clockwise from
+x). The *episode* frame, in which observations report the pose, has its origin at the episode's start position,
its +x axis along the start heading and +y to the left, yaw counter-clockwise from the start heading: Habitat's
GPS+compass, made right-handed (Habitat's GPS reports ``(forward, right)``; an adapter negates the second
component).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from drivenav.envs.episode import Episode


class Action(IntEnum):
    """Discrete actions, numbered as in Habitat's ObjectNav task."""

    STOP = 0
    MOVE_FORWARD = 1
    TURN_LEFT = 2
    TURN_RIGHT = 3


@dataclass(frozen=True)
class Pose:
    """A planar pose: position in metres and yaw in radians (counter-clockwise)."""

    x: float
    y: float
    yaw: float

    def compose(self, local: Pose) -> Pose:
        """``self * local``: the pose ``local`` (given in this pose's frame) in the parent frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose(
            self.x + c * local.x - s * local.y,
            self.y + s * local.x + c * local.y,
            self.yaw + local.yaw,
        )

    def inverse(self) -> Pose:
        """The pose of the parent frame's origin in this pose's frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose(-c * self.x - s * self.y, s * self.x - c * self.y, -self.yaw)


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics in pixels. The camera looks along the agent's heading, level with the floor."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @staticmethod
    def from_hfov(width: int, height: int, hfov_deg: float) -> CameraIntrinsics:
        """Square pixels with the given horizontal field of view (Habitat's convention)."""
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return CameraIntrinsics(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0)


@dataclass(frozen=True)
class SimConfig:
    """Simulator settings; defaults follow the Habitat ObjectNav set-up the paper uses."""

    width: int = 640
    height: int = 480
    hfov_deg: float = 79.0
    camera_height: float = 0.88
    min_depth: float = 0.5
    max_depth: float = 5.0
    agent_radius: float = 0.18
    agent_height: float = 0.88
    forward_step: float = 0.25
    turn_angle_deg: float = 30.0
    max_steps: int = 500
    success_distance: float = 0.25
    grid_resolution: float = 0.05

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return CameraIntrinsics.from_hfov(self.width, self.height, self.hfov_deg)


@dataclass(frozen=True)
class Observation:
    """One egocentric observation.

    ``rgb`` is (H, W, 3) uint8; ``depth`` is (H, W) float32 z-depth in metres clipped to
    ``[min_depth, max_depth]``; ``semantic`` is (H, W) int32 instance ids (0 = none) or None where the world
    has no ground truth; ``pose`` is in the episode frame.
    """

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    semantic: NDArray[np.int32] | None
    pose: Pose
    intrinsics: CameraIntrinsics
    step: int
    collided: bool


class Env(Protocol):
    """What every world implements: the embedded simulator, Habitat, a robot bridge."""

    def reset(self, episode: Episode) -> Observation: ...

    def step(self, action: Action) -> Observation: ...
