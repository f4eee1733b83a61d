"""The pure ``cmd_vel`` closed loop of one discrete action on odometry (paper Sec. V-E): no ROS types, so that
it is tested without a robot; :class:`drivenav.robot.ros.nodes.RosMotionExecutor` publishes its commands."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from enum import Enum

from drivenav.grid import wrap_angle
from drivenav.robot.parts import MotionResult
from drivenav.types import Action, Pose


@dataclass(frozen=True)
class CmdVelConfig:
    """The closed-loop ``cmd_vel`` executor of one discrete action (paper Sec. V-E: the agent's 0.25 m steps and
    30 degree turns on the real robot).

    Speeds in m/s and rad/s: a proportional command ``gain`` x (remaining distance or angle), saturated to
    ``[min_*, *_speed]``; forward motion also holds the start heading. Done within ``forward_tolerance`` metres of
    the step or ``turn_tolerance_deg`` of the turn; ``timeout`` seconds in all; a forward step that gains less
    than ``stall_distance`` in ``stall_time`` seconds is blocked (a collision).
    """

    forward_step: float = 0.25
    turn_angle_deg: float = 30.0
    linear_speed: float = 0.2
    min_linear_speed: float = 0.05
    angular_speed: float = 0.6
    min_angular_speed: float = 0.15
    gain: float = 2.0
    forward_tolerance: float = 0.01
    turn_tolerance_deg: float = 2.0
    timeout: float = 10.0
    stall_time: float = 1.0
    stall_distance: float = 0.02

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"CmdVelConfig.{item.name} must be positive and finite, got {value}")
        if self.min_linear_speed > self.linear_speed:
            raise ValueError(f"CmdVelConfig.min_linear_speed must be at most linear_speed, got {self.min_linear_speed}")
        if self.min_angular_speed > self.angular_speed:
            raise ValueError(
                f"CmdVelConfig.min_angular_speed must be at most angular_speed, got {self.min_angular_speed}"
            )


@dataclass(frozen=True)
class VelocityCommand:
    """One ``geometry_msgs/Twist``: forward speed (m/s) and yaw rate (rad/s, counter-clockwise)."""

    linear: float
    angular: float


class Outcome(Enum):
    """How an action ended."""

    DONE = "done"
    TIMEOUT = "timeout"
    BLOCKED = "blocked"

    def result(self) -> MotionResult:
        """Blocked is Habitat's ``collided``; only done counts as completed."""
        return MotionResult(collided=self is Outcome.BLOCKED, completed=self is Outcome.DONE)


class CmdVelController:
    """The pure closed loop of one MOVE_FORWARD, TURN_LEFT or TURN_RIGHT on odometry: each :meth:`step` takes the
    current odometry pose and the time since the start and returns the velocity to command or the outcome."""

    def __init__(self, action: Action, start: Pose, config: CmdVelConfig | None = None) -> None:
        if action == Action.STOP:
            raise ValueError("STOP has no closed loop: stop at once")
        self.config = config or CmdVelConfig()
        self.action = action
        self.start = start
        sign = 1.0 if action == Action.TURN_LEFT else -1.0
        self._target_yaw = start.yaw + sign * math.radians(self.config.turn_angle_deg)
        self._progress_mark = (0.0, 0.0)  # (progress, elapsed) when the forward progress last grew enough

    def step(self, pose: Pose, elapsed: float) -> VelocityCommand | Outcome:
        """The command for odometry ``pose`` at ``elapsed`` seconds, or how the action ended."""
        return self._forward(pose, elapsed) if self.action == Action.MOVE_FORWARD else self._turn(pose, elapsed)

    def _forward(self, pose: Pose, elapsed: float) -> VelocityCommand | Outcome:
        c = self.config
        dx, dy = pose.x - self.start.x, pose.y - self.start.y
        progress = dx * math.cos(self.start.yaw) + dy * math.sin(self.start.yaw)  # along the start heading
        remaining = c.forward_step - progress
        if remaining <= c.forward_tolerance:
            return Outcome.DONE
        if elapsed >= c.timeout:
            return Outcome.TIMEOUT
        if progress >= self._progress_mark[0] + c.stall_distance:
            self._progress_mark = (progress, elapsed)
        elif elapsed - self._progress_mark[1] >= c.stall_time:
            return Outcome.BLOCKED
        heading_error = wrap_angle(self.start.yaw - pose.yaw)
        return VelocityCommand(
            _clip(c.gain * remaining, c.min_linear_speed, c.linear_speed),
            _clip(c.gain * heading_error, -c.angular_speed, c.angular_speed),
        )

    def _turn(self, pose: Pose, elapsed: float) -> VelocityCommand | Outcome:
        c = self.config
        error = wrap_angle(self._target_yaw - pose.yaw)
        if abs(error) <= math.radians(c.turn_tolerance_deg):
            return Outcome.DONE
        if elapsed >= c.timeout:
            return Outcome.TIMEOUT
        return VelocityCommand(
            0.0, math.copysign(_clip(c.gain * abs(error), c.min_angular_speed, c.angular_speed), error)
        )


def _clip(value: float, low: float, high: float) -> float:
    return min(max(value, low), high)
