"""The saved episode trace (``RUN_DIR/traces/<id>.json``): what the runner writes and every picture reads.

:class:`EpisodeTrace` is one episode as the runner saw it: world-frame poses (``positions``, ``yaws``, one per step from
the start, and ``heights`` where the agent left height 0: a building's floors), the actions taken, where the agent's
trajectory segments start, the agent's typed events (:mod:`drivenav.agent.trace`; event points and bearings are in the
episode frame), the per-step module timings (``step_ms``, :mod:`drivenav.eval.timings`) and, for an episode an exception
ended, that exception.

The file layout has a version. Version 1 is the layout written before the key ``version`` existed (its files
have no such key; the oldest lack ``segment_starts`` and ``step_ms`` too); version 2 is the same keys plus
``"version": 2``. Both load; a newer version is refused with one :class:`~drivenav.errors.InputError` (a newer
drivenav wrote it), so that a reader never misreads a layout it does not know.
"""

from __future__ import annotations

import json
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from drivenav.agent.trace import Event, Point, event_from_dict
from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.validation import Fields

TRACE_VERSION = 2
"""The layout :meth:`EpisodeTrace.to_json` writes."""
FIRST_VERSION = 1  # a file without a "version" key
StepColumns = dict[str, list[float]]
"""Per-step timings by module: ``{"mapping": [ms at step 1, ms at step 2, ...], ...}``."""
ValueT = TypeVar("ValueT")


@dataclass(frozen=True)
class EpisodeError:
    """The exception that ended an episode (the runner catches it; the record keeps ``type: message``)."""

    type: str
    message: str
    traceback: str

    @staticmethod
    def of(exc: BaseException) -> EpisodeError:
        lines = traceback.format_exception(type(exc), exc, exc.__traceback__)
        return EpisodeError(type(exc).__name__, str(exc), "".join(lines))

    def summary(self) -> str:
        """``Type: message``, as the episode record's ``error``."""
        return f"{self.type}: {self.message}"

    def to_json(self) -> dict[str, str]:
        return {"type": self.type, "message": self.message, "traceback": self.traceback}


@dataclass(frozen=True)
class EpisodeTrace:
    """One episode's trace; ``version`` is the layout it was read from (:data:`TRACE_VERSION` when built)."""

    episode_id: str
    scene_id: str
    positions: tuple[Point, ...]
    yaws: tuple[float, ...]
    actions: tuple[int, ...] = ()
    heights: tuple[float, ...] = ()
    segment_starts: tuple[int, ...] = ()
    events: tuple[Event, ...] = ()
    step_ms: StepColumns = field(default_factory=dict)
    error: EpisodeError | None = None
    version: int = TRACE_VERSION

    def to_json(self) -> JsonObject:
        """The file's JSON object, in the current layout: the keys of version 1 (``error`` only for an episode an
        exception ended), then ``"version"``."""
        data: JsonObject = {
            "episode_id": self.episode_id,
            "scene_id": self.scene_id,
            "positions": [list(p) for p in self.positions],
            "yaws": list(self.yaws),
            "actions": list(self.actions),
            "segment_starts": list(self.segment_starts),
            "events": [event.to_dict() for event in self.events],
            "step_ms": {module: list(values) for module, values in self.step_ms.items()},
        }
        if self.error is not None:
            data["error"] = self.error.to_json()
        if self.heights:
            data["heights"] = list(self.heights)
        data["version"] = TRACE_VERSION
        return data

    @staticmethod
    def from_json(data: object, source: str | Path = "trace") -> EpisodeTrace:
        """A trace from its file's JSON (version 1 or 2); anything else is an :class:`InputError` naming ``source``
        and the field: a newer version, an unknown event kind, a missing pose list, a value of the wrong type."""
        fields = Fields(source)
        obj = fields.mapping(data, "", required=("positions", "yaws"))
        version = _version(obj, fields)
        positions = tuple(
            _point(p, f"positions[{k}]", fields) for k, p in enumerate(fields.sequence(obj["positions"], "positions"))
        )
        yaws = tuple(fields.number(y, f"yaws[{k}]") for k, y in enumerate(fields.sequence(obj["yaws"], "yaws")))
        if len(yaws) != len(positions):
            raise fields.error("yaws", f"one yaw per position ({len(positions)})", len(yaws))
        no_heights: tuple[float, ...] = ()
        heights = _optional(obj, "heights", no_heights, lambda v: _numbers(v, "heights", fields))
        if heights and len(heights) != len(positions):
            raise fields.error("heights", f"one height per position ({len(positions)})", len(heights))
        return EpisodeTrace(
            episode_id=_optional(obj, "episode_id", "", lambda v: _text(v, "episode_id", fields)),
            scene_id=_optional(obj, "scene_id", "", lambda v: _text(v, "scene_id", fields)),
            positions=positions,
            yaws=yaws,
            actions=_optional(obj, "actions", (), lambda v: _integers(v, "actions", fields)),
            segment_starts=_optional(obj, "segment_starts", (), lambda v: _integers(v, "segment_starts", fields)),
            events=_optional(obj, "events", (), lambda v: _events(v, fields)),
            step_ms=_optional(obj, "step_ms", {}, lambda v: _step_ms(v, fields)),
            error=_optional(obj, "error", None, lambda v: _error(v, fields)),
            heights=heights,
            version=version,
        )


# ---------------------------------------------------------------------------------------------- readers of fields


def _version(obj: JsonObject, fields: Fields) -> int:
    version = obj.get("version", FIRST_VERSION)
    if isinstance(version, bool) or not isinstance(version, int) or not FIRST_VERSION <= version <= TRACE_VERSION:
        expected = (
            f"a trace version this drivenav reads ({FIRST_VERSION} to {TRACE_VERSION}; a newer drivenav wrote it)"
        )
        raise fields.error("version", expected, version)
    return version


def _optional(obj: JsonObject, key: str, default: ValueT, read: Callable[[Any], ValueT]) -> ValueT:
    """``read`` of ``obj[key]``, or ``default`` when the key is missing (older version-1 files)."""
    return read(obj[key]) if key in obj else default


def _text(value: Any, field: str, fields: Fields) -> str:
    if not isinstance(value, str):
        raise fields.error(field, "a string", value)
    return value


def _point(value: Any, field: str, fields: Fields) -> Point:
    x, y = fields.numbers(value, field, 2)
    return x, y


def _numbers(value: Any, field: str, fields: Fields) -> tuple[float, ...]:
    return tuple(fields.number(item, f"{field}[{k}]") for k, item in enumerate(fields.sequence(value, field)))


def _integers(value: Any, field: str, fields: Fields) -> tuple[int, ...]:
    return tuple(fields.integer(item, f"{field}[{k}]") for k, item in enumerate(fields.sequence(value, field)))


def _events(value: Any, fields: Fields) -> tuple[Event, ...]:
    events = fields.sequence(value, "events")
    return tuple(
        event_from_dict(fields.mapping(item, f"events[{k}]"), fields.source, f"events[{k}]")
        for k, item in enumerate(events)
    )


def _step_ms(value: Any, fields: Fields) -> StepColumns:
    columns = fields.mapping(value, "step_ms")
    return {
        str(module): [
            fields.number(v, f"step_ms.{module}[{k}]") for k, v in enumerate(fields.sequence(ms, f"step_ms.{module}"))
        ]
        for module, ms in columns.items()
    }


def _error(value: Any, fields: Fields) -> EpisodeError:
    keys = ("type", "message", "traceback")
    error = fields.mapping(value, "error", keys=keys, required=keys)
    return EpisodeError(*(_text(error[key], f"error.{key}", fields) for key in keys))


def read_trace(path: Path) -> EpisodeTrace | None:
    """The trace saved at ``path``, or None where it is missing, torn or malformed: a reader of a run's timings
    leaves that episode's steps out."""
    try:
        return EpisodeTrace.from_json(json.loads(path.read_text(encoding="utf-8")), path)
    except (OSError, ValueError, InputError):
        return None
