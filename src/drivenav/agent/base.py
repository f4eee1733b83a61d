"""The agent interface shared by DRIVE-Nav, its baselines and the reference agents.

An agent is reset with the goal text, then maps each :class:`Observation` to an :class:`Action`. It marks the
start of every frontier-selection segment (for the revisit metric), counts its reasoning-model calls, and says
why it stopped.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field

from drivenav.agent.trace import StopEvent, Trace
from drivenav.semantics.protocols import FLOOR_KIND, HINTS_KIND
from drivenav.types import Action, GroundTruth, Observation, SimConfig


@dataclass(frozen=True)
class ModelCounters:
    """What an episode cost in model calls and what the semantic loop did (Sec. IV-B, IV-C; Table VII)."""

    vlm_calls_by_kind: dict[str, int] = field(default_factory=dict)
    vlm_latency_ms: dict[str, float] = field(default_factory=dict)
    vlm_fallbacks: int = 0
    enrich_rounds: int = 0
    verifications: dict[str, int] = field(default_factory=dict)
    phrase: str = ""

    def split(self, total: int) -> CallSplit | None:
        """The episode's ``total`` model calls split by model (:func:`split_calls`)."""
        return split_calls(self.vlm_calls_by_kind, total)


REASONER, SCORER = "reasoner", "scorer"
CALL_MODELS: Mapping[str, str] = {
    "select_direction": REASONER,
    "propose_prompt": REASONER,
    "verify": REASONER,
    HINTS_KIND: REASONER,
    FLOOR_KIND: REASONER,
    "score": SCORER,
}
"""The model behind each :class:`~drivenav.semantics.protocols.ModelCall` kind, the one place that tells them apart:
the reasoner's questions (a VLM or LLM, seconds a call) and the image-text scorer's frames (``score``: VLFM and
ApexNav score every frame, ``drive-nav-plus`` its new views; milliseconds a call)."""


@dataclass(frozen=True)
class CallSplit:
    """An episode's model calls by model: the reasoner's and the image-text scorer's."""

    reasoner: int
    scorer: int


def split_calls(by_kind: Mapping[str, int], total: int) -> CallSplit | None:
    """``total`` calls split by :data:`CALL_MODELS`, or None where the counts by kind cannot tell: a record without
    them (a record's ``vlm_calls_by_kind`` that does not add up to its ``vlm_calls``) or with a kind of no known
    model (a plug-in's)."""
    if sum(by_kind.values()) != total or not set(by_kind) <= set(CALL_MODELS):
        return None
    return CallSplit(
        *(sum(n for kind, n in by_kind.items() if CALL_MODELS[kind] == model) for model in (REASONER, SCORER))
    )


CounterValue = int | float | dict[str, int]
"""One counter of an episode: a number, or counts by kind (decisions by trigger, steps by activity)."""


@dataclass(frozen=True)
class BodyCounters:
    """What the body did in an episode, for every exploration method: steps by activity (``start_scan``, ``scan``,
    ``sweep``, ``follow``, ``enrich``, ``approach``, ``escape`` for collision recovery, ``stop``: the explorer names
    its own activities, the body adds ``approach``, ``escape`` and ``stop``) and turn reversals (a left turn right
    after a right one, or the reverse: oscillation); and what became of target detections (Sec. IV-C): candidates
    entered into the object map, accepted, and set aside because the agent could not get to them."""

    steps_by_activity: dict[str, int] = field(default_factory=dict)
    turn_reversals: int = 0
    target_candidates: int = 0
    targets_accepted: int = 0
    targets_set_aside: int = 0


@dataclass(frozen=True)
class ExplorerCounters:
    """The exploration method's own counters in an episode: its explorer's name (``explorer.name``) and the counters
    it keeps (:meth:`~drivenav.agent.explorer.Explorer.counters`, e.g. DRIVE-Nav's labels, inspection events and
    decisions by trigger)."""

    name: str
    counters: dict[str, CounterValue] = field(default_factory=dict)


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

    def start_models(self) -> None:
        """Build the agent's models now, before its first episode (none here: agents with models build them), so
        that a model that cannot be built stops a run before any worker starts."""
        return None

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

    def episode_stats(self) -> ModelCounters:
        """Model calls by kind, enrichment and verification of this episode (none for model-free agents)."""
        return ModelCounters()

    def body_counters(self) -> BodyCounters:
        """Steps by activity and target detections of this episode (none for agents without the body)."""
        return BodyCounters()

    def explorer_counters(self) -> ExplorerCounters | None:
        """The exploration method's name and counters of this episode (None for agents without an explorer)."""
        return None

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
