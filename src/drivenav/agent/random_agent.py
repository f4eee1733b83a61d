"""A random walker: the floor any navigation method must beat. It never calls STOP."""

from __future__ import annotations

import numpy as np

from drivenav.agent.base import Agent
from drivenav.types import Action, GroundTruth, Observation

FORWARD_PROBABILITY = 0.6


class RandomAgent(Agent):
    """Moves forward with probability 0.6, else turns; turns after a collision."""

    name = "random"

    def reset(self, goal_text: str, seed: int, truth: GroundTruth | None = None) -> None:
        super().reset(goal_text, seed, truth)
        self._rng = np.random.default_rng(seed)

    def decide(self, observation: Observation) -> Action:
        draw = self._rng.random()
        if observation.collided or draw >= FORWARD_PROBABILITY:
            return Action.TURN_LEFT if draw < 0.5 * (1.0 + FORWARD_PROBABILITY) else Action.TURN_RIGHT
        return Action.MOVE_FORWARD
