"""The episode record: one typed line of ``episodes.jsonl`` per finished episode, and its readers.

Every key of the results contract (``episode_id``, ``scene_id``, ``object_category``, ``success``, ``spl``, ``steps``,
``path_length``, ``geodesic_distance``, ``distance_to_goal``, ``revisits``, ``collisions``, ``stop_reason``,
``vlm_calls``) keeps its name. The world's measures may be ``None`` (a robot has no ground truth: they are
``null``, never 0). The agent's model statistics (:class:`~drivenav.agent.base.ModelCounters`) and the body's counters
(:class:`~drivenav.agent.base.BodyCounters`: steps by activity, turn reversals, target detections) are written flat,
beside the other keys; the exploration method's counters under ``explorer`` (``{"name": ..., "counters": {...}}``,
:class:`~drivenav.agent.base.ExplorerCounters`; ``null`` for an agent without an explorer); ``retraced_revisits`` and
``retraced_m`` are the segmentation-free revisit count (:func:`drivenav.metrics.retraced`); ``trace`` names the
episode's trace file in the run directory ("" when it could not be written). ``schema_version`` 1 is the untyped
record written before it existed, 2 the record before the decision counters, 3 the record before ``trace``, 4 the
record before ``explorer``, whose DRIVE-Nav counters were flat beside the others: all read the same (the flat counters
of a record before 5 become its explorer's, the explorer named by the record's method). Every value is checked against
its field's type and range when read, by every reader (a resume, ``compare``, ``report``, ``viz``): ``success`` is 0,
1 or null, ``spl`` lies in [0, 1], and every other number (steps, distances, counts, latencies) is finite and >= 0
(``success: "yes"``, ``spl: 55.5`` or ``steps: -40`` names the line and field).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

from drivenav.agent.base import BodyCounters, CallSplit, CounterValue, ExplorerCounters, ModelCounters
from drivenav.envs.base import EpisodeMeasures
from drivenav.errors import InputError
from drivenav.jsonstream import JsonObject
from drivenav.methods import REFERENCE_AGENTS, method_named

SCHEMA_VERSION = 5
ERROR = "error"  # the stop reason and failure cause of an episode that an exception ended

LEGACY_EXPLORER_KEYS = (
    "labels_created",
    "labels_merged",
    "labels_removed",
    "inspection_events",
    "decisions_by_reason",
    "dead_end_decisions",
    "followed_through_relabel",
    "selected_lost",
    "labels_reidentified",
)
"""The DRIVE-Nav counters a record before schema 5 kept flat beside the others (``decisions_by_reason`` is now
the explorer's ``decisions``)."""


@dataclass(frozen=True)
class EpisodeRecord:
    """One finished episode: what it was, what the world measured, what the agent did."""

    episode_id: str
    scene_id: str
    object_category: str
    agent: str
    steps: int
    revisits: int
    stop_reason: str
    failure_cause: str
    success: int | None = None
    spl: float | None = None
    path_length: float | None = None
    geodesic_distance: float | None = None
    distance_to_goal: float | None = None
    collisions: int | None = None
    retraced_revisits: int | None = None
    retraced_m: float | None = None
    canonical_category: str = ""
    synonym: bool = False
    vlm_calls: int = 0
    error: str = ""
    privileged: tuple[str, ...] = ()
    stats: ModelCounters = field(default_factory=ModelCounters)
    body: BodyCounters = field(default_factory=BodyCounters)
    explorer: ExplorerCounters | None = None
    trace: str = ""
    schema_version: int = SCHEMA_VERSION

    @property
    def is_error(self) -> bool:
        return self.stop_reason == ERROR

    @property
    def calls(self) -> CallSplit | None:
        """``vlm_calls`` split into the reasoner's and the image-text scorer's (None where the record cannot tell:
        :func:`~drivenav.agent.base.split_calls`)."""
        return self.stats.split(self.vlm_calls)

    def to_json(self) -> JsonObject:
        """The JSON object written to ``episodes.jsonl`` (model statistics and the body's counters flat beside the
        other keys, the explorer's under ``explorer``)."""
        data = asdict(self)
        data.update(data.pop("stats"))
        data.update(data.pop("body"))
        data["privileged"] = list(self.privileged)
        return data

    @staticmethod
    def from_json(data: object, source: str | Path = "episodes.jsonl") -> EpisodeRecord:
        """Read a record (any schema version); a missing key or a value of the wrong type is an
        :class:`InputError` naming the field."""
        if not isinstance(data, dict):
            raise InputError(source, "record", "a JSON object", type(data).__name__)
        stats = ModelCounters(**_typed(ModelCounters, data, source))
        body = BodyCounters(**_typed(BodyCounters, data, source))
        explorer = _explorer(data, source)
        data = {**data, "privileged": data.get("privileged", [])}
        values = _typed(EpisodeRecord, data, source, skip=frozenset({"stats", "body", "explorer"}))
        values["privileged"] = tuple(values["privileged"])
        values.setdefault("schema_version", 1)
        values.setdefault("canonical_category", data.get("object_category", ""))
        try:
            return EpisodeRecord(**values, stats=stats, body=body, explorer=explorer)
        except TypeError as error:
            raise InputError(source, "record", "the keys of an episode record", str(error)) from None


def _explorer(data: JsonObject, source: str | Path) -> ExplorerCounters | None:
    """The record's explorer and its counters; a record before schema 5 had its DRIVE-Nav counters flat, and its
    explorer is its method's (none for a reference agent)."""
    if "explorer" in data:
        return _explorer_object(data["explorer"], source)
    agent = data.get("agent")
    if not isinstance(agent, str) or agent in REFERENCE_AGENTS:
        return None
    method = method_named(agent)
    legacy = {key: data[key] for key in LEGACY_EXPLORER_KEYS if key in data}
    if "decisions_by_reason" in legacy:
        legacy["decisions"] = legacy.pop("decisions_by_reason")
    return _explorer_object({"name": method.explorer if method else "directions", "counters": legacy}, source)


def _explorer_object(value: object, source: str | Path) -> ExplorerCounters | None:
    """``{"name": str, "counters": {name: number or {kind: count}}}``, or null."""
    if value is None:
        return None
    if not isinstance(value, dict) or not isinstance(value.get("name"), str):
        raise InputError(source, "record.explorer", '{"name": the explorer, "counters": {...}} or null', value)
    counters = value.get("counters", {})
    if not (isinstance(counters, dict) and all(_is_counter(k, v) for k, v in counters.items())):
        expected = f"a mapping of counter names to numbers or to {{kind: count}}, each {NON_NEGATIVE}"
        raise InputError(source, "record.explorer.counters", expected, counters)
    typed: dict[str, CounterValue] = dict(counters)
    return ExplorerCounters(value["name"], typed)


def _is_counter(name: str, value: object) -> bool:
    """A counter: a number, or counts by kind; finite and >= 0."""
    if isinstance(value, dict):
        typed = all(isinstance(k, str) and _fits(v, "int") for k, v in value.items())
    else:
        typed = _fits(value, "int") or _fits(value, "float")
    return typed and not _out_of_range(name, value)


_SCALARS: dict[str, tuple[type, ...]] = {"str": (str,), "int": (int,), "bool": (bool,), "float": (int, float)}


def _typed(kind: type, data: JsonObject, source: str | Path, skip: frozenset[str] = frozenset()) -> JsonObject:
    """The keys of ``data`` that are fields of the dataclass ``kind``, each checked against its annotation."""
    values = {}
    for item in fields(kind):
        if item.name in skip or item.name not in data:
            continue
        annotation = str(item.type)
        value = data[item.name]
        if not _has_type(value, annotation):
            raise InputError(source, f"record.{item.name}", annotation, value)
        expected = _out_of_range(item.name, value)
        if expected:
            raise InputError(source, f"record.{item.name}", expected, value)
        values[item.name] = value
    return values


_BOUNDED = {"success": "0, 1 or null", "spl": "a number in [0, 1] or null"}
"""What the bounded fields expect; every other number of a record (steps, distances, counts, latencies) is finite
and >= 0."""
NON_NEGATIVE = "a finite number >= 0"


def _out_of_range(name: str, value: object) -> str:
    """What the field ``name`` expects when ``value`` (of its type) lies out of its range, else "" (NaN is in no
    range)."""
    numbers = _numbers(value)
    if name == "success":
        fits = all(number in (0, 1) for number in numbers)
    elif name == "spl":
        fits = all(0 <= number <= 1 for number in numbers)
    else:
        fits = all((isinstance(number, int) or math.isfinite(number)) and number >= 0 for number in numbers)
    return "" if fits else _BOUNDED.get(name, NON_NEGATIVE)


def _numbers(value: object) -> list[int | float]:
    """The numbers in a record's value (itself, or a dictionary's values; booleans are no numbers)."""
    if isinstance(value, dict):
        return [number for item in value.values() for number in _numbers(item)]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [value]
    return []


def _has_type(value: object, annotation: str) -> bool:
    """Whether a JSON value fits a field annotation of the record (``int | None``, ``dict[str, float]``,
    ``tuple[str, ...]``; a boolean is no number)."""
    return any(_fits(value, option.strip()) for option in annotation.split("|"))


def _fits(value: object, option: str) -> bool:
    if option == "None":
        return value is None
    if option.startswith("dict["):
        inner = option[len("dict[") : -1].split(",", 1)[1].strip()
        return isinstance(value, dict) and all(isinstance(k, str) and _has_type(v, inner) for k, v in value.items())
    if option.startswith("tuple["):
        return isinstance(value, list) and all(isinstance(v, str) for v in value)
    if option not in _SCALARS or (isinstance(value, bool) and option != "bool"):
        return False
    return isinstance(value, _SCALARS[option])


def checked_measures(measures: EpisodeMeasures) -> EpisodeMeasures:
    """A world's measures, when each fits its record field's type and range; else a :class:`ValueError` naming it
    (the episode then ends in an error: no record that the readers refuse is ever written, e.g. from a robot
    reporting ``success: 7``)."""
    annotations = {item.name: str(item.type) for item in fields(EpisodeRecord)}
    for item in fields(EpisodeMeasures):
        value, annotation = getattr(measures, item.name), annotations.get(item.name)
        if annotation is None:
            continue  # not recorded (target_seen)
        expected = _out_of_range(item.name, value) if _has_type(value, annotation) else annotation
        if expected:
            raise ValueError(f"the world measured {item.name} = {value!r}; expected {expected}")
    return measures


def failure_cause(success: int | None, stop_reason: str, target_seen: bool | None) -> str:
    """Why an episode failed ("" for successes and where the world cannot tell).

    ``error``: an exception ended it (never a navigation failure); ``false_positive_stop``: STOP away from every
    goal; ``missed_target``: a goal was in view at some step but not reached; otherwise the target was never in
    view and the cause is the stop reason: ``timeout``, ``no_frontier``, or ``target_never_seen``.
    """
    if stop_reason == ERROR:
        return ERROR
    if success is None or success:
        return ""
    if stop_reason == "target_reached":
        return "false_positive_stop"
    if target_seen:
        return "missed_target"
    return stop_reason if stop_reason in ("timeout", "no_frontier") else "target_never_seen"


MISSED_CAUSES = (
    "never_detected",
    "rejected_by_verification",
    "detected_not_accepted",
    "set_aside_unreachable",
    "accepted_not_reached",
)


def missed_cause(record: EpisodeRecord) -> str:
    """Why a ``missed_target`` episode (a goal was in view, never reached) missed it, from the agent's side
    (Sec. IV-C): the detector never produced a candidate; verification rejected every candidate; candidates were
    still pending at the end; the agent could not get to one and set it aside; or one was accepted but not
    reached in the step budget."""
    body = record.body
    if body.target_candidates == 0:
        return "never_detected"
    if body.targets_set_aside:
        return "set_aside_unreachable"
    if body.targets_accepted:
        return "accepted_not_reached"
    if record.stats.verifications.get("rejected", 0):
        return "rejected_by_verification"
    return "detected_not_accepted"


def read_records(
    path: Path, episode_ids: frozenset[str] | None = None, agent: str | None = None
) -> list[EpisodeRecord]:
    """The records of ``episodes.jsonl``, read only (a torn last line, from a kill or a run still writing it, is
    left out, never cut: only the run's own writer repairs it, under its lock). A second record of one episode, one
    of an episode not in ``episode_ids`` (when given: the run's), or one of another agent than the run's
    (:func:`check_agent`) is an :class:`InputError` naming its line."""
    if not path.exists():
        return []
    data = path.read_bytes()
    records: list[EpisodeRecord] = []
    first_line: dict[str, int] = {}
    for number, line in enumerate(data[: data.rfind(b"\n") + 1].splitlines(), start=1):
        if not line.strip():
            continue
        try:
            record = EpisodeRecord.from_json(json.loads(line), f"{path}:{number}")
        except ValueError:
            raise InputError(path, f"line {number}", "one JSON object per line") from None
        check_agent(record, agent, f"{path}:{number}")
        first = first_line.get(record.episode_id)
        if first is not None:
            got = f"a second record of episode {record.episode_id!r} (the first is on line {first})"
            raise InputError(path, f"line {number}", "one record per episode", got)
        if episode_ids is not None and record.episode_id not in episode_ids:
            got = f"a record of episode {record.episode_id!r}, which is not in this run"
            raise InputError(path, f"line {number}", "records of this run's episodes only", got)
        first_line[record.episode_id] = number
        records.append(record)
    return records


def check_agent(record: EpisodeRecord, agent: str | None, source: str) -> None:
    """Refuse a record of another agent than its run's (``agent``: the ``run.agent`` its ``run.json`` names, as
    written: a method, a preset, an ablation or a plug-in's, installed or not; None for records without a
    ``run.json``, not checked): one :class:`InputError` naming the line and ``record.agent``. A run's records are
    its agent's results only (``vlfm`` in a ``drive-nav`` run, an agent no registry knows, are not)."""
    if agent is not None and record.agent != agent:
        expected = f"{agent!r}, the agent of this run (run.json's run.agent)"
        raise InputError(source, "record.agent", expected, record.agent)


def cut_torn_tail(path: Path) -> None:
    """Cut a torn last line (an append a kill interrupted) off ``episodes.jsonl``: for the run's writer alone, under
    its lock, before it appends."""
    if not path.exists():
        return
    data = path.read_bytes()
    keep = data.rfind(b"\n") + 1
    if keep < len(data):
        with path.open("r+b") as handle:
            handle.truncate(keep)
