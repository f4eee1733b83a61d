"""The oracle: follows the geodesic shortest path to the nearest goal view point and STOPs.

It validates world, episodes and metrics together: on any scene set it must reach success rate 1.0 and
SPL >= 0.95. Each step it simulates a forward step for every reachable heading (multiples of the turn angle),
keeps its heading while that is within a hair of the best one, and otherwise turns toward the best heading.
"""

from __future__ import annotations

import math

from drivenav.agent.base import Agent, PrivilegedInfo
from drivenav.envs.motion import forward_step
from drivenav.types import Action, Observation

KEEP_HEADING_SLACK = 0.01  # metres: keep the heading if its step ends this close to the best step
COLLISION_PENALTY = 0.02  # metres: prefer a clean step over sliding along a wall when both progress alike
MIN_PROGRESS = 1e-3  # metres of geodesic progress that count as progress
STOP_MARGIN = 0.02  # metres inside the success distance before stopping


class OracleAgent(Agent):
    """Privileged shortest-path follower (one segment per episode)."""

    name = "oracle"
    uses_privileged = True

    def set_privileged(self, info: PrivilegedInfo) -> None:
        self._info = info

    def decide(self, observation: Observation) -> Action:
        info = self._info
        pose = info.start_pose.compose(observation.pose)
        here = info.goal_field.at(pose.x, pose.y)  # the metric's own distance to goal
        if here <= self.sim.success_distance - STOP_MARGIN:
            return self.stop("target_reached")
        turn = math.radians(self.sim.turn_angle_deg)
        headings = round(2.0 * math.pi / turn)
        steps = [self._step_outcome(pose.x, pose.y, pose.yaw + k * turn) for k in range(headings)]
        if min(distance for distance, _ in steps) > here - MIN_PROGRESS:
            return self.stop("target_reached" if here <= self.sim.success_distance else "stuck")
        cost = [distance + (COLLISION_PENALTY if collided else 0.0) for distance, collided in steps]
        best_k = min(range(headings), key=lambda k: (cost[k], min(k, headings - k)))
        if cost[0] <= cost[best_k] + KEEP_HEADING_SLACK and steps[0][0] < here - MIN_PROGRESS:
            return Action.MOVE_FORWARD
        return Action.TURN_LEFT if best_k <= headings // 2 else Action.TURN_RIGHT

    def _step_outcome(self, x: float, y: float, yaw: float) -> tuple[float, bool]:
        """Distance to goal after a forward step along ``yaw``, and whether that step collides."""
        info = self._info
        nx, ny, collided = forward_step(info.navigable, info.scene.grid, x, y, yaw, self.sim.forward_step)
        return info.goal_field.at(nx, ny), collided
