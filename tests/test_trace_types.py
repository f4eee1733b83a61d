"""Typed episode traces: every registered event survives its JSON form, version-1 trace files (written before
the ``version`` key) still load and write back the same keys and values, and an unknown event kind or a newer
trace version is one clear InputError naming the field."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from drivenav.agent.trace import (
    EVENT_TYPES,
    DetectionEvent,
    DirectionSelected,
    Event,
    FloorDropped,
    FloorJudged,
    FloorLooked,
    FloorReached,
    FloorSetOff,
    InspectionStarted,
    InspectionVoid,
    OpaqueEvent,
    ScanStarted,
    StopEvent,
    TargetAccepted,
    TargetRejected,
    TargetSetAside,
    VerificationEvent,
    ViewCaptured,
    event_from_dict,
    is_builtin,
)
from drivenav.errors import InputError
from drivenav.eval.trace import TRACE_VERSION, EpisodeError, EpisodeTrace

V1_TRACE = Path(__file__).parent / "data" / "trace_v1.json"  # written by the runner before traces had a version

EXAMPLES: tuple[Event, ...] = (
    ScanStarted(0, 12),
    InspectionStarted(3, (1, 2), (0.5, -1.25)),
    ViewCaptured(4, 2, 1.5, 0.02, True),
    DirectionSelected(5, 2, -0.75, (3.5, -1.0), (0, 2, 4), "scan"),
    DirectionSelected(6, 4, 0.25, (1.0, 2.0), (4,), "inspection", fallback=True),
    DetectionEvent(7, "potted plant", 0.83, (2.0, 4.5)),
    VerificationEvent(8, 1, "uncertain"),
    TargetAccepted(9, 1, (2.0, 4.5)),
    TargetRejected(10, 3, (-1.0, 0.5), "verification"),
    TargetSetAside(11, 5, (6.0, 1.0), 40),
    StopEvent(12, "target_reached"),
    InspectionVoid(13, (1, 2)),
    FloorJudged(14, 0, "other", "0.00 of the goal's rooms among kitchen, living room, dining room"),
    FloorSetOff(15, 0, (4.5, -2.0), True, "judged"),
    FloorLooked(20, 0, (6.6, 2.4)),
    FloorDropped(30, 0, (4.5, -2.0), "approach_steps"),
    FloorReached(40, 1, 0, True),
)


def _json(value: object) -> object:
    """``value`` as it comes back from a file (tuples become lists)."""
    return json.loads(json.dumps(value))


def test_every_registered_event_type_has_an_example() -> None:
    """drivenav's own kinds (plug-ins' events, which other tests of this process import, register too)."""
    assert {type(event) for event in EXAMPLES} == {cls for cls in EVENT_TYPES.values() if is_builtin(cls)}
    assert all(cls.kind == kind for kind, cls in EVENT_TYPES.items())


@pytest.mark.parametrize("event", EXAMPLES, ids=lambda e: f"{e.kind}-{e.step}")
def test_event_round_trips_through_json(event: Event) -> None:
    data = _json(event.to_dict())
    assert isinstance(data, dict) and data["kind"] == event.kind and data["step"] == event.step
    back = event_from_dict(data)
    assert type(back) is type(event) and back == event
    assert all(isinstance(getattr(back, name), tuple) for name, v in vars(event).items() if isinstance(v, tuple))


def test_a_field_added_with_a_default_may_be_missing() -> None:
    data = {"kind": "direction_selected", "step": 1, "label": 2, "bearing": 0.5, "goal": [1, 2], "candidates": [2]}
    assert event_from_dict({**data, "reason": "scan"}) == DirectionSelected(1, 2, 0.5, (1.0, 2.0), (2,), "scan")
    with pytest.raises(InputError, match=r"field 'event\.reason'"):
        event_from_dict(data)  # a field without a default is required


def test_an_unknown_kind_is_kept_as_opaque_data() -> None:
    """A kind of no class here (a plug-in's, read without it) is kept as saved and written back as it was."""
    data = {"kind": "teleport", "step": 1, "to": [1.0, {"room": "hall"}]}
    event = event_from_dict(data, "t.json", "events[3]")
    assert isinstance(event, OpaqueEvent) and event.name == "teleport" and event.to_dict() == data


def test_a_kind_that_is_no_text_or_an_unknown_one_without_a_step_is_named() -> None:
    with pytest.raises(InputError, match=r"t\.json: field 'events\[3\]\.kind'"):
        event_from_dict({"kind": 4, "step": 1}, "t.json", "events[3]")
    with pytest.raises(InputError, match=r"t\.json: field 'events\[3\]\.step'"):
        event_from_dict({"kind": "teleport", "step": "one"}, "t.json", "events[3]")


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"step": "one"}, "step"),
        ({"goal": [1.0]}, "goal"),
        ({"fallback": "yes"}, "fallback"),
        ({"label": 1.5}, "label"),
    ],
)
def test_a_mistyped_event_field_is_named(change: dict[str, object], field: str) -> None:
    data = {**EXAMPLES[3].to_dict(), **change}
    with pytest.raises(InputError, match=rf"field 'event\.{field}'"):
        event_from_dict(data)


def test_a_missing_required_event_field_is_named() -> None:
    data = {k: v for k, v in EXAMPLES[5].to_dict().items() if k != "score"}
    with pytest.raises(InputError, match=r"field 'event\.score'"):
        event_from_dict(data)


def _trace() -> EpisodeTrace:
    return EpisodeTrace(
        episode_id="ep-1",
        scene_id="scene/a",
        positions=((0.0, 0.0), (0.25, 0.0), (0.25, 0.0)),
        yaws=(0.0, 0.0, 0.5236),
        actions=(1, 3),
        segment_starts=(0,),
        events=EXAMPLES,
        step_ms={"mapping": [1.5, 2.0], "policy": [0.1, 0.2]},
    )


def test_episode_trace_round_trips_and_writes_its_version() -> None:
    trace = _trace()
    data = _json(trace.to_json())
    assert isinstance(data, dict) and data["version"] == TRACE_VERSION == 2
    assert list(data) == [
        "episode_id", "scene_id", "positions", "yaws", "actions", "segment_starts", "events", "step_ms", "version"
    ]  # fmt: skip
    assert EpisodeTrace.from_json(data) == trace


def test_an_error_is_written_under_error_and_read_back() -> None:
    try:
        raise RuntimeError("the world fell over")
    except RuntimeError as exc:
        error = EpisodeError.of(exc)
    trace = replace(_trace(), error=error)
    data = _json(trace.to_json())
    assert isinstance(data, dict) and data["error"]["type"] == "RuntimeError"
    assert (
        "the world fell over" in data["error"]["traceback"] and error.summary() == "RuntimeError: the world fell over"
    )
    assert EpisodeTrace.from_json(data) == trace


def test_a_version_1_file_loads_and_writes_back_the_same_keys_and_values() -> None:
    data = json.loads(V1_TRACE.read_text(encoding="utf-8"))
    assert "version" not in data
    trace = EpisodeTrace.from_json(data, V1_TRACE)
    assert trace.version == 1 and trace.episode_id == data["episode_id"]
    assert len(trace.positions) == len(trace.yaws) == len(trace.actions) + 1
    assert {type(e) for e in trace.events} >= {ScanStarted, ViewCaptured, DirectionSelected}
    assert _json(trace.to_json()) == {**data, "version": TRACE_VERSION}


def test_the_oldest_version_1_files_lack_timings_and_segments() -> None:
    data = json.loads(V1_TRACE.read_text(encoding="utf-8"))
    older = {k: v for k, v in data.items() if k not in ("step_ms", "segment_starts")}
    trace = EpisodeTrace.from_json(older)
    assert trace.step_ms == {} and trace.segment_starts == () and len(trace.events) == len(data["events"])


@pytest.mark.parametrize("version", [3, 0, "2", True])
def test_an_unknown_version_is_one_clear_error(version: object) -> None:
    data = {**_trace().to_json(), "version": version}
    with pytest.raises(InputError, match=r"trace\.json: field 'version': expected a trace version this drivenav reads"):
        EpisodeTrace.from_json(data, "trace.json")


def test_an_unknown_event_kind_in_a_file_is_kept_and_written_back() -> None:
    data = _json(_trace().to_json())
    assert isinstance(data, dict)
    data["events"][2] = {"kind": "teleport", "step": 3}
    trace = EpisodeTrace.from_json(data, "trace.json")
    assert isinstance(trace.events[2], OpaqueEvent) and _json(trace.to_json()) == data


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"positions": None}, "positions"),
        ({"yaws": [0.0]}, "yaws"),
        ({"actions": ["forward"]}, r"actions\[0\]"),
        ({"step_ms": {"mapping": ["slow"]}}, r"step_ms\.mapping\[0\]"),
        ({"error": {"type": "E"}}, r"error\.message"),
    ],
)
def test_a_malformed_trace_names_the_field(change: dict[str, object], field: str) -> None:
    data = {**_trace().to_json(), **change}
    with pytest.raises(InputError, match=rf"field '{field}'"):
        EpisodeTrace.from_json(data, "trace.json")


def test_a_trace_without_poses_is_refused() -> None:
    data = {k: v for k, v in _trace().to_json().items() if k != "yaws"}
    with pytest.raises(InputError, match=r"field 'yaws'"):
        EpisodeTrace.from_json(data)
    with pytest.raises(InputError, match=r"field '<document>'"):
        EpisodeTrace.from_json([1, 2])


def test_an_event_class_must_name_a_kind_of_its_own() -> None:
    with pytest.raises(TypeError, match="own kind"):

        class Unnamed(StopEvent):
            pass

    with pytest.raises(TypeError, match="already"):

        class Twin(Event):
            kind = "stop"
