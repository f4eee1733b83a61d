"""The agent interface shared by DRIVE-Nav, its baselines and the reference agents.

An agent is reset with the goal text, then maps each :class:`Observation` to an :class:`Action`. It marks the
start of every frontier-selection segment (for the revisit metric), counts its reasoning-model calls, and says
why it stopped.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.trace import StopEvent, Trace
from drivenav.envs.geodesic import GeodesicField
from drivenav.envs.scene import Scene
from drivenav.semantics.protocols import SemanticLabels
from drivenav.types import Action, Observation, Pose, SimConfig


@dataclass(frozen=True)
class PrivilegedInfo:
    """Ground truth handed only to agents that declare ``uses_privileged`` (the oracle)."""

    scene: Scene
    navigable: NDArray[np.bool_]
    goal_field: GeodesicField
    start_pose: Pose


class Agent(ABC):
    """Base class: segment bookkeeping, stop reason and model-call counting."""

    name: str = "agent"
    uses_privileged: ClassVar[bool] = False

    def __init__(self, sim: SimConfig) -> None:
        self.sim = sim
        self.goal_text = ""
        self.segment_starts: list[int] = []
        self.stop_reason: str | None = None
        self.trace = Trace()
        self.step = 0
        self.step_timings: list[dict[str, float]] = []  # per step: module -> ms (saved in the run's traces)

    def reset(self, goal_text: str, seed: int, labels: SemanticLabels | None = None) -> None:
        """Start an episode looking for ``goal_text``.

        ``seed`` makes any randomness reproducible; ``labels`` say what the world's semantic instance ids mean
        (for ground-truth grounding), where the world has them.
        """
        self.goal_text = goal_text
        self.segment_starts = []
        self.stop_reason = None
        self.trace = Trace()
        self.step = 0
        self.step_timings = []

    def set_privileged(self, info: PrivilegedInfo) -> None:  # noqa: B027 (optional hook, no-op by default)
        """Receive ground truth (only called when ``uses_privileged`` is true)."""

    @property
    def model_calls(self) -> int:
        """Reasoning-model (VLM) calls made this episode."""
        return 0

    def episode_stats(self) -> dict[str, object]:
        """Agent-specific fields for the episode record (model calls by kind, enrichment, verification)."""
        return {}

    def start_segment(self, step: int) -> None:
        """Mark that a new frontier-selection segment begins at ``step`` (paper Sec. V-C revisits)."""
        if not self.segment_starts or self.segment_starts[-1] != step:
            self.segment_starts.append(step)

    def stop(self, reason: str) -> Action:
        """Issue STOP and remember why."""
        self.stop_reason = reason
        self.trace.add(StopEvent(self.step, reason))
        return Action.STOP

    def act(self, observation: Observation) -> Action:
        """The next action (``step`` is kept for events and segments)."""
        self.step = observation.step
        if self.step == 0:
            self.start_segment(0)
        return self.decide(observation)

    @abstractmethod
    def decide(self, observation: Observation) -> Action:
        """The policy itself."""
