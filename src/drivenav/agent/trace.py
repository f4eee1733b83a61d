"""The episode trace: typed events an agent emits, saved by the evaluator and read by the visualiser.

Every event carries the step at which it happened and a ``kind``, the name its JSON form goes by. Each event class
registers itself under its kind when it is defined (:data:`EVENT_TYPES`), so that :func:`event_from_dict` rebuilds
the right dataclass from a saved trace and readers dispatch on the event's type, never on its kind string.
``to_dict`` gives the JSON form (no images): the kind, the step, then the fields in declaration order.

A plug-in explorer's events are classes of its own kinds. A reader without the plug-in (or one whose saved fields do
not fit its class) keeps such an event as an :class:`OpaqueEvent`, its JSON as it was, and never fails the trace on
it; only drivenav's own kinds (:func:`is_builtin`) are read strictly. :func:`json_problem` says what makes an
event's JSON form unsafe to save (the body checks every plug-in event when it receives it).

This module stays pure (no files): reading and writing trace files is the evaluator's (``drivenav.eval.trace``).
"""

from __future__ import annotations

import json
import math
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

    def __init_subclass__(cls, register: bool = True, **kwargs: object) -> None:
        """Register the new event class under its own ``kind`` (one class per kind: a clash is a bug); ``register``
        false for :class:`OpaqueEvent`, which stands for kinds of no class."""
        super().__init_subclass__(**kwargs)
        if not register:
            return
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
class FloorLooked(Event):
    """On floor ``floor`` the agent looked for a way down suspected behind a railing, from ``point`` (episode frame;
    ``agent.floors.railings``, docs/floors.md)."""

    floor: int
    point: Point
    kind: ClassVar[str] = "floor_looked"


@dataclass(frozen=True)
class FloorDropped(Event):
    """On floor ``floor`` the agent gave up the way whose entry is ``entry`` (episode frame; docs/floors.md) for
    ``reason``: ``approach_steps`` (not reached within that many steps) or ``no_climb`` (no rise within
    ``probe_steps`` forward steps on it), both for good; ``unreachable`` (no navigable point near its entry on the
    map) or ``no_path`` (the planner found none), both tried again ``retry_steps`` later; ``climb_steps`` (still
    between two levels after that many steps: back down the way it came, the way given up for good)."""

    floor: int
    entry: Point
    reason: str
    kind: ClassVar[str] = "floor_dropped"


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


@dataclass(frozen=True)
class OpaqueEvent(Event, register=False):
    """An event of a kind this reader has no class for (a plug-in's, read without the plug-in): its ``name`` (the
    saved kind) and its other fields as saved (``data``, JSON values); written back as it was read."""

    name: str
    data: Mapping[str, object] = field(default_factory=dict)
    kind: ClassVar[str] = "opaque"

    def to_dict(self) -> JsonObject:
        return {"kind": self.name, "step": self.step, **self.data}


def event_name(event: Event) -> str:
    """The kind an event is saved under (an opaque event's own)."""
    return event.name if isinstance(event, OpaqueEvent) else event.kind


def event_fields(event: Event) -> dict[str, object]:
    """An event's saved fields but its kind and step, in order."""
    data = event.to_dict()
    return {key: value for key, value in data.items() if key not in ("kind", "step")}


def is_builtin(event: Event | type[Event]) -> bool:
    """Whether an event's class is one of drivenav's own (not a plug-in's, not opaque)."""
    cls = event if isinstance(event, type) else type(event)
    return cls is not OpaqueEvent and cls.__module__.split(".")[0] == "drivenav"


MAX_EVENT_CHARS = 65536
"""The most characters one event's JSON form may take (a plug-in event larger than this is refused)."""
MAX_INTEGER = 2**53
"""Integers in a record or a trace stay below this: every JSON reader reads them exactly."""


def json_problem(value: object, where: str = "") -> str:
    """What makes ``value`` no safe JSON value ("" when it is one): only strings, booleans, null, integers below
    :data:`MAX_INTEGER` in size, finite floats, lists (or tuples) and objects with string keys."""
    if value is None or isinstance(value, (str, bool)):
        return ""
    if isinstance(value, int):
        return "" if abs(value) < MAX_INTEGER else f"{where or 'value'} is an integer of {abs(value).bit_length()} bits"
    if isinstance(value, float):
        return "" if math.isfinite(value) else f"{where or 'value'} is {value}"
    if isinstance(value, (list, tuple)):
        return next((p for k, item in enumerate(value) if (p := json_problem(item, f"{where}[{k}]"))), "")
    if isinstance(value, Mapping):
        for key, item in value.items():
            if not isinstance(key, str):
                return f"{where or 'value'} has the key {key!r}, not a string"
            problem = json_problem(item, f"{where}.{key}" if where else key)
            if problem:
                return problem
        return ""
    return f"{where or 'value'} is a {type(value).__name__}, no JSON value"


def event_problem(event: object) -> str:
    """What makes an event unfit for the trace ("" when it fits): no :class:`Event`, a field that is no safe JSON
    value (:func:`json_problem`), or a JSON form over :data:`MAX_EVENT_CHARS` characters."""
    if not isinstance(event, Event):
        return f"a {type(event).__name__} is no trace Event"
    try:
        data = event.to_dict()
    except Exception as error:  # a field asdict cannot copy
        return f"its fields cannot be read ({type(error).__name__}: {error})"
    problem = json_problem(data)
    if problem:
        return problem
    size = len(json.dumps(data))
    return f"its JSON form is {size} characters (at most {MAX_EVENT_CHARS})" if size > MAX_EVENT_CHARS else ""


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
    not have are ignored. A kind of no class here, or a plug-in's whose fields do not fit its class, is an
    :class:`OpaqueEvent`. A kind that is no string, a step that is no integer, or a missing or mistyped field of
    drivenav's own kinds is an :class:`InputError` naming ``source`` and ``where`` (e.g. ``events[3]``)."""
    kind = data.get("kind")
    if not isinstance(kind, str):
        raise InputError(source, f"{where}.kind", "an event kind (a string)", kind)
    cls = EVENT_TYPES.get(kind)
    if cls is not None and is_builtin(cls):
        return _event(cls, data, source, where)
    if cls is not None:
        try:
            return _event(cls, data, source, where)
        except Exception:  # a plug-in's class that does not take its own saved fields: kept as saved
            pass
    return _opaque(kind, data, source, where)


def _opaque(kind: str, data: Mapping[str, object], source: str | Path, where: str) -> OpaqueEvent:
    """An event of a kind without a class, kept as saved (its step must be an integer)."""
    step = data.get("step")
    if isinstance(step, bool) or not isinstance(step, int):
        raise InputError(source, f"{where}.step", "an integer", step)
    return OpaqueEvent(step, kind, {key: value for key, value in data.items() if key not in ("kind", "step")})


def _event(cls: type[Event], data: Mapping[str, object], source: str | Path, where: str) -> Event:
    """The event of class ``cls`` whose JSON form is ``data``."""
    kind = cls.kind
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
