"""The episode trace: typed events an agent emits, saved by the evaluator and read by the visualiser.

Every event carries the step at which it happened and a ``kind``; ``to_dict`` gives its JSON form (no images).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar

Point = tuple[float, float]


@dataclass(frozen=True)
class Event:
    step: int
    kind: ClassVar[str] = "event"

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, **asdict(self)}


@dataclass(frozen=True)
class ScanStarted(Event):
    """A full 360 deg scan begins (the start scan, or every decision in ``direction-360``)."""

    turns: int
    kind: ClassVar[str] = "scan"


@dataclass(frozen=True)
class InspectionStarted(Event):
    """Directions lacking views triggered a sweep: their labels and the yaws to face, in visiting order."""

    labels: tuple[int, ...]
    target_yaws: tuple[float, ...]
    kind: ClassVar[str] = "inspection"


@dataclass(frozen=True)
class ViewCaptured(Event):
    """A representative view was recorded (``updated``: it replaced an older, less aligned one)."""

    label: int
    yaw: float
    error: float
    updated: bool
    kind: ClassVar[str] = "view"


@dataclass(frozen=True)
class DirectionSelected(Event):
    """The reasoner chose a direction among the candidates."""

    label: int
    bearing: float
    goal: Point
    candidates: tuple[int, ...]
    reason: str
    fallback: bool = False
    kind: ClassVar[str] = "direction_selected"


@dataclass(frozen=True)
class DetectionEvent(Event):
    """The grounder found the target phrase; ``position`` is the projected world point."""

    phrase: str
    score: float
    position: Point
    kind: ClassVar[str] = "detection"


@dataclass(frozen=True)
class VerificationEvent(Event):
    """A cross-frame verification judgement on a candidate: ``sure``, ``uncertain`` or ``not``."""

    candidate: int
    outcome: str
    kind: ClassVar[str] = "verification"


@dataclass(frozen=True)
class TargetAccepted(Event):
    candidate: int
    position: Point
    kind: ClassVar[str] = "target_accepted"


@dataclass(frozen=True)
class TargetRejected(Event):
    candidate: int
    position: Point
    reason: str
    kind: ClassVar[str] = "target_rejected"


@dataclass(frozen=True)
class TargetSetAside(Event):
    """A target the agent could not get to is left alone until step ``until`` (not rejected: only a verification
    can say it is not the target)."""

    candidate: int
    position: Point
    until: int
    kind: ClassVar[str] = "target_set_aside"


@dataclass(frozen=True)
class StopEvent(Event):
    reason: str
    kind: ClassVar[str] = "stop"


@dataclass
class Trace:
    """The events of one episode, in order."""

    events: list[Event] = field(default_factory=list)

    def add(self, event: Event) -> None:
        self.events.append(event)

    def of_kind(self, kind: str) -> list[Event]:
        return [e for e in self.events if e.kind == kind]

    def to_json(self) -> list[dict[str, Any]]:
        return [e.to_dict() for e in self.events]
