"""The robot side's pluggable parts: where observations come from and what executes an action.

A :class:`SensorSource` gives synchronised frames (RGB, depth, odometry pose, optionally a LiDAR scan) from ROS 2
topics, a ROS 2 bag or the embedded world; a :class:`MotionExecutor` turns one discrete action into motion (ROS 2
``cmd_vel`` closed on odometry, Nav2 behaviours, or the embedded world). :class:`drivenav.robot.server.RobotServer`
serves any pair over the protocol.

Frames. ``pose`` is the robot base in the source's odometry frame (x, y in metres, yaw counter-clockwise, and the
height z where the odometry gives one, 0 otherwise); ``gimbal_yaw`` is the camera's yaw relative to the base (a head
camera turned on a gimbal), so the camera looks along ``pose.yaw + gimbal_yaw``. ``scan`` holds LiDAR returns as
(N, 3) float32 points ``(x forward, y left, z up)`` in the base frame, ``z`` measured from the floor (the mounting
transform is applied by the source).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from drivenav.types import Action, CameraIntrinsics, Pose


@dataclass(frozen=True)
class SensorFrame:
    """One synchronised set of readings. ``depth`` is float32 metres, NaN where the sensor had no return;
    ``semantic`` (int32 instance ids) only from a simulated robot."""

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    pose: Pose
    intrinsics: CameraIntrinsics
    stamp: float
    gimbal_yaw: float = 0.0
    gimbal_pitch: float = 0.0
    scan: NDArray[np.float32] | None = None
    semantic: NDArray[np.int32] | None = None


@dataclass(frozen=True)
class MotionResult:
    """What executing one action did: whether the robot was blocked (Habitat's ``collided``) and whether it
    finished in time."""

    collided: bool
    completed: bool = True


class SensorSource(Protocol):
    """Synchronised sensor frames from a robot, a bag or a simulator."""

    def read(self) -> SensorFrame:
        """The latest synchronised frame (blocks until one is available; raises TimeoutError if none comes)."""
        ...

    def close(self) -> None:
        """Release topics, files or the simulator."""
        ...


class MotionExecutor(Protocol):
    """Executes one discrete action: MOVE_FORWARD by the step length, TURN_LEFT / TURN_RIGHT by the turn angle."""

    def execute(self, action: Action) -> MotionResult:
        """Carry out ``action`` and return when the robot has stopped (STOP: stop at once)."""
        ...

    def stop(self) -> None:
        """Stop moving now (the deadman, Ctrl-C on the brain, a STOP message)."""
        ...


class HeldStill:
    """A robot that does not move (bag replays, bring-up checks of the sensors): every action completes at once."""

    def execute(self, action: Action) -> MotionResult:
        return MotionResult(collided=False)

    def stop(self) -> None:
        """Nothing moves."""
