"""The episode trace: typed events an agent emits, saved by the evaluator and read by the visualiser.

Every event carries the step at which it happened and a ``kind``, the name its JSON form goes by. Each event class
registers itself under its kind when it is defined (:data:`EVENT_TYPES`), so that :func:`event_from_dict` rebuilds
the right dataclass from a saved trace and readers dispatch on the event's type, never on its kind string.
``to_dict`` gives the JSON form (no images): the kind, the step, then the fields in declaration order.

This module stays pure (no files): reading and writing trace files is the evaluator's (``drivenav.eval.trace``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import MISSING, asdict, dataclass, field, fields
from functools import cache
from pathlib import Path
from typing import ClassVar, TypeVar, get_args, get_origin, get_type_hints

from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject

Point = tuple[float, float]
EventT = TypeVar("EventT", bound="Event")
Convert = Callable[[object], object]

EVENT_TYPES: dict[str, type[Event]] = {}
"""Every event class by its ``kind``; a class enters it when it is defined (:meth:`Event.__init_subclass__`)."""


@dataclass(frozen=True)
class Event:
    step: int
    kind: ClassVar[str] = "event"

    def __init_subclass__(cls, **kwargs: object) -> None:
        """Register the new event class under its own ``kind`` (one class per kind: a clash is a bug)."""
        super().__init_subclass__(**kwargs)
        if "kind" not in cls.__dict__:
            raise TypeError(f"event class {cls.__name__} must name its own kind")
        if cls.kind in EVENT_TYPES:
            raise TypeError(f"event kind {cls.kind!r} of {cls.__name__} is already {EVENT_TYPES[cls.kind].__name__}'s")
        EVENT_TYPES[cls.kind] = cls

    def to_dict(self) -> JsonObject:
        """The JSON form: ``kind``, then the fields (tuples stay tuples; ``json.dumps`` writes them as lists)."""
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
class InspectionVoid(Event):
    """An inspection event ended without a decision: every direction that started it (``labels``) was gone by the
    sweep's end, so following went on (``explorer.directions.skip_void_events``, beyond the paper)."""

    labels: tuple[int, ...]
    kind: ClassVar[str] = "inspection_void"


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
    """A verified candidate became the target the agent approaches."""

    candidate: int
    position: Point
    kind: ClassVar[str] = "target_accepted"


@dataclass(frozen=True)
class TargetRejected(Event):
    """A candidate is no longer the target (``reason``: e.g. a verification said it is not)."""

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
class FloorJudged(Event):
    """The floor question was asked on floor ``floor`` (docs/floors.md): the reasoner's ``guess`` (``this``,
    ``other`` or ``unsure``) and its note."""

    floor: int
    guess: str
    note: str
    kind: ClassVar[str] = "floor_judged"


@dataclass(frozen=True)
class FloorSetOff(Event):
    """The agent set off from floor ``floor`` for stairs (``up`` or down) whose entry is ``entry`` (episode frame),
    because the floor was explored (``reason`` ``explored``), judged without the target (``judged``) or had its
    share of the steps (``share``)."""

    floor: int
    entry: Point
    up: bool
    reason: str
    kind: ClassVar[str] = "floor_set_off"


@dataclass(frozen=True)
class FloorReached(Event):
    """The agent arrived on floor ``floor`` (``new``: first reached) by stairs from floor ``came_from``."""

    floor: int
    came_from: int
    new: bool
    kind: ClassVar[str] = "floor_reached"


@dataclass(frozen=True)
class StopEvent(Event):
    """The agent called STOP (``reason``: why)."""

    reason: str
    kind: ClassVar[str] = "stop"


def of_type(events: Iterable[Event], kind: type[EventT]) -> list[EventT]:
    """The events of one type, in order."""
    return [event for event in events if isinstance(event, kind)]


@dataclass
class Trace:
    """The events of one episode, in order."""

    events: list[Event] = field(default_factory=list)

    def add(self, event: Event) -> None:
        self.events.append(event)

    def of_type(self, kind: type[EventT]) -> list[EventT]:
        return of_type(self.events, kind)


# ---------------------------------------------------------------------------------------------- from JSON


def event_from_dict(data: Mapping[str, object], source: str | Path = "trace", where: str = "event") -> Event:
    """The event whose JSON form (:meth:`Event.to_dict`) is ``data``: the class its ``kind`` names, JSON lists
    back to tuples. A field with a default may be missing (traces written before it existed); keys the class does
    not have are ignored. An unknown kind or a missing or mistyped field is an :class:`InputError` naming ``source``
    and ``where`` (e.g. ``events[3]``)."""
    kind = data.get("kind")
    cls = EVENT_TYPES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise InputError(
            source, f"{where}.kind", f"an event kind drivenav knows ({', '.join(sorted(EVENT_TYPES))})", kind
        )
    values: dict[str, object] = {}
    for name, (convert, required) in _fields_of(cls.kind).items():
        if name not in data:
            if required:
                raise InputError(source, f"{where}.{name}", f"the {name} of a {kind} event", "nothing")
            continue
        try:
            values[name] = convert(data[name])
        except (TypeError, ValueError) as error:
            raise InputError(source, f"{where}.{name}", str(error), data[name]) from None
    return cls(**values)  # type: ignore[arg-type]  # converted to each field's type above


@cache
def _fields_of(kind: str) -> dict[str, tuple[Convert, bool]]:
    """Per field of the event class of ``kind``: the converter from its JSON value and whether it is required."""
    cls = EVENT_TYPES[kind]
    hints = get_type_hints(cls)
    return {
        f.name: (_converter(hints[f.name]), f.default is MISSING and f.default_factory is MISSING) for f in fields(cls)
    }


def _converter(hint: object) -> Convert:
    """From a JSON value to a value of the field type ``hint`` (int, float, str, bool, or tuples of them)."""
    if get_origin(hint) is tuple:
        args = get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            item = _converter(args[0])
            return lambda value: tuple(item(v) for v in _sequence(value, None))
        items = [_converter(a) for a in args]
        return lambda value: tuple(c(v) for c, v in zip(items, _sequence(value, len(items)), strict=True))
    scalars: dict[object, Convert] = {int: _integer, float: _real, str: _text, bool: _flag}
    if hint not in scalars:
        raise TypeError(f"an event field of type {hint} has no JSON form")
    return scalars[hint]


def _sequence(value: object, length: int | None) -> list[object]:
    if not isinstance(value, (list, tuple)) or (length is not None and len(value) != length):
        raise ValueError("a list" + (f" of {length}" if length is not None else ""))
    return list(value)


def _integer(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not float(value).is_integer():
        raise ValueError("an integer")
    return int(value)


def _real(value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError("a number")
    return float(value)


def _text(value: object) -> str:
    if not isinstance(value, str):
        raise ValueError("a string")
    return value


def _flag(value: object) -> bool:
    if not isinstance(value, bool):
        raise ValueError("true or false")
    return value
