"""The agent interface shared by DRIVE-Nav, its baselines and the reference agents.

An agent is reset with the goal text, then maps each :class:`Observation` to an :class:`Action`. It marks the
start of every frontier-selection segment (for the revisit metric), counts its reasoning-model calls, and says
why it stopped.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

from drivenav.agent.trace import StopEvent, Trace
from drivenav.types import Action, GroundTruth, Observation, SimConfig


@dataclass(frozen=True)
class ModelStats:
    """What an episode cost in model calls and what the semantic loop did (Sec. IV-B, IV-C; Table VII)."""

    vlm_calls_by_kind: dict[str, int] = field(default_factory=dict)
    vlm_latency_ms: dict[str, float] = field(default_factory=dict)
    vlm_fallbacks: int = 0
    enrich_rounds: int = 0
    verifications: dict[str, int] = field(default_factory=dict)
    phrase: str = ""


@dataclass(frozen=True)
class DecisionStats:
    """How an episode's exploration went (Sec. IV-A b-c): direction labels the tracker created, merged and
    removed; inspection events; reasoner decisions by trigger (``scan``, ``inspection``, ``vanished``, ``stuck``);
    decisions at a dead end (no still-relevant direction in the forward 240 deg, so the rear range was offered);
    how often the followed direction was carried over a relabelling (``followed_through_relabel``) or lost its label
    with no successor (``selected_lost``); fresh labels recognised as a retired direction (removed, or merged
    away) back at its place (``labels_reidentified``); steps by activity (``start_scan``, ``scan``, ``sweep``,
    ``follow``, ``enrich``, ``approach``, ``escape`` for collision recovery, ``stop``) and turn reversals (a left turn
    right after a right one, or the reverse: oscillation); and what became of target detections (Sec. IV-C):
    candidates entered into the object map, accepted, and set aside because the agent could not get to them."""

    labels_created: int = 0
    labels_merged: int = 0
    labels_removed: int = 0
    inspection_events: int = 0
    decisions_by_reason: dict[str, int] = field(default_factory=dict)
    dead_end_decisions: int = 0
    followed_through_relabel: int = 0
    selected_lost: int = 0
    labels_reidentified: int = 0
    steps_by_activity: dict[str, int] = field(default_factory=dict)
    turn_reversals: int = 0
    target_candidates: int = 0
    targets_accepted: int = 0
    targets_set_aside: int = 0


class Agent(ABC):
    """Base class: segment bookkeeping, stop reason and model-call counting.

    ``requires`` lists the privileged inputs (:data:`~drivenav.types.PRIVILEGED_KINDS`) the agent needs; the
    runner gives ground truth only to agents that ask, and refuses a world that cannot provide it.
    """

    name: str = "agent"
    requires: frozenset[str] = frozenset()

    def __init__(self, sim: SimConfig) -> None:
        self.sim = sim
        self.goal_text = ""
        self.segment_starts: list[int] = []
        self.stop_reason: str | None = None
        self.trace = Trace()
        self.step = 0
        self.step_timings: list[dict[str, float]] = []  # per step: module -> ms (saved in the run's traces)

    def reset(self, goal_text: str, seed: int, truth: GroundTruth | None = None) -> None:
        """Start an episode looking for ``goal_text``.

        ``seed`` makes any randomness reproducible; ``truth`` holds the ground truth this agent ``requires``.
        """
        self.goal_text = goal_text
        self.segment_starts = []
        self.stop_reason = None
        self.trace = Trace()
        self.step = 0
        self.step_timings = []

    def end_episode(self) -> None:
        """Release what only the finished episode needed (its trace and step timings here; subclasses add their maps),
        once its record and trace are taken, so that the next scene loads beside as little as possible;
        :meth:`reset` builds it again."""
        self.trace = Trace()
        self.step_timings = []

    @property
    def model_calls(self) -> int:
        """Reasoning-model (VLM) calls made this episode."""
        return 0

    def episode_stats(self) -> ModelStats:
        """Model calls by kind, enrichment and verification of this episode (none for model-free agents)."""
        return ModelStats()

    def decision_stats(self) -> DecisionStats:
        """Labels, inspection events, decisions and steps by activity of this episode (none for other agents)."""
        return DecisionStats()

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
