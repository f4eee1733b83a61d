"""The oracle: follows the geodesic shortest path to the nearest goal view point and STOPs.

It validates world, episodes and metrics together: on any scene set it must reach success rate 1.0 and SPL >= 0.95, up
and down the stairs of buildings too (its poses carry their height). Each step it simulates a forward step for every
reachable heading (multiples of the turn angle), keeps its heading while that is within a hair of the best one, and
otherwise turns toward the best heading.
"""

from __future__ import annotations

import math

from drivenav.agent.base import Agent
from drivenav.types import GEODESIC, Action, GeodesicOracle, GroundTruth, Observation, Pose

KEEP_HEADING_SLACK = 0.01  # metres: keep the heading if its step ends this close to the best step
COLLISION_PENALTY = 0.02  # metres: prefer a clean step over sliding along a wall when both progress alike
MIN_PROGRESS = 1e-3  # metres of geodesic progress that count as progress
STOP_MARGIN = 0.02  # metres inside the success distance before stopping


class OracleAgent(Agent):
    """Privileged shortest-path follower (one segment per episode)."""

    name = "oracle"
    requires = frozenset({GEODESIC})

    def reset(self, goal_text: str, seed: int, truth: GroundTruth | None = None) -> None:
        super().reset(goal_text, seed, truth)
        if truth is None or truth.geodesic is None:
            raise ValueError("the oracle needs the world's geodesic ground truth")
        self._geodesic: GeodesicOracle = truth.geodesic

    def decide(self, observation: Observation) -> Action:
        geodesic = self._geodesic
        pose = geodesic.start_pose.compose(observation.pose)
        here = geodesic.distance(pose)  # the metric's own distance to goal
        if here <= self.sim.success_distance - STOP_MARGIN:
            return self.stop("target_reached")
        turn = math.radians(self.sim.turn_angle_deg)
        headings = round(2.0 * math.pi / turn)
        steps = [self._step_outcome(Pose(pose.x, pose.y, pose.yaw + k * turn, pose.z)) for k in range(headings)]
        if min(distance for distance, _ in steps) > here - MIN_PROGRESS:
            return self.stop("target_reached" if here <= self.sim.success_distance else "stuck")
        cost = [distance + (COLLISION_PENALTY if collided else 0.0) for distance, collided in steps]
        best_k = min(range(headings), key=lambda k: (cost[k], min(k, headings - k)))
        if cost[0] <= cost[best_k] + KEEP_HEADING_SLACK and steps[0][0] < here - MIN_PROGRESS:
            return Action.MOVE_FORWARD
        return Action.TURN_LEFT if best_k <= headings // 2 else Action.TURN_RIGHT

    def _step_outcome(self, pose: Pose) -> tuple[float, bool]:
        """Distance to goal after a forward step from ``pose``, and whether that step collides."""
        reached, collided = self._geodesic.forward(pose)
        return self._geodesic.distance(reached), collided
