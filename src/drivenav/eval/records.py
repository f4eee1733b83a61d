"""The episode record: one typed line of ``episodes.jsonl`` per finished episode, and its readers.

Every key issue 2 named (``episode_id``, ``scene_id``, ``object_category``, ``success``, ``spl``, ``steps``,
``path_length``, ``geodesic_distance``, ``distance_to_goal``, ``revisits``, ``collisions``, ``stop_reason``,
``vlm_calls``) keeps its name. The world's measures may be ``None`` (a robot has no ground truth: they are
``null``, never 0). The agent's model statistics (:class:`~drivenav.agent.base.ModelStats`) and decision counters
(:class:`~drivenav.agent.base.DecisionStats`) are written flat, beside the other keys; ``retraced_revisits`` and
``retraced_m`` are the segmentation-free revisit count (:func:`drivenav.metrics.retraced`). ``schema_version`` 1
is the untyped record written before it existed, 2 the record before the decision counters: both read the same.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from drivenav.agent.base import DecisionStats, ModelStats
from drivenav.errors import InputError

SCHEMA_VERSION = 3
ERROR = "error"  # the stop reason and failure cause of an episode that an exception ended

_STATS_KEYS = tuple(f.name for f in fields(ModelStats))
_DECISION_KEYS = tuple(f.name for f in fields(DecisionStats))


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
    stats: ModelStats = field(default_factory=ModelStats)
    decisions: DecisionStats = field(default_factory=DecisionStats)
    schema_version: int = SCHEMA_VERSION

    @property
    def is_error(self) -> bool:
        return self.stop_reason == ERROR

    def to_json(self) -> dict[str, Any]:
        """The JSON object written to ``episodes.jsonl`` (model statistics and decision counters flat beside the
        other keys)."""
        data = asdict(self)
        data.update(data.pop("stats"))
        data.update(data.pop("decisions"))
        data["privileged"] = list(self.privileged)
        return data

    @staticmethod
    def from_json(data: Any, source: str | Path = "episodes.jsonl") -> EpisodeRecord:
        """Read a record (either schema version); a missing key or a wrong type is an :class:`InputError`."""
        if not isinstance(data, dict):
            raise InputError(source, "record", "a JSON object", type(data).__name__)
        stats = ModelStats(**{k: data[k] for k in _STATS_KEYS if k in data})
        decisions = DecisionStats(**{k: data[k] for k in _DECISION_KEYS if k in data})
        known = {f.name for f in fields(EpisodeRecord)} - {"stats", "decisions"}
        values = {k: v for k, v in data.items() if k in known}
        values["privileged"] = tuple(values.get("privileged", ()))
        values.setdefault("schema_version", 1)
        values.setdefault("canonical_category", data.get("object_category", ""))
        try:
            return EpisodeRecord(**values, stats=stats, decisions=decisions)
        except TypeError as error:
            raise InputError(source, "record", "the keys of an episode record", str(error)) from None


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
    decisions = record.decisions
    if decisions.target_candidates == 0:
        return "never_detected"
    if decisions.targets_set_aside:
        return "set_aside_unreachable"
    if decisions.targets_accepted:
        return "accepted_not_reached"
    if record.stats.verifications.get("rejected", 0):
        return "rejected_by_verification"
    return "detected_not_accepted"


def read_records(path: Path) -> list[EpisodeRecord]:
    """The records of ``episodes.jsonl``; a torn last line (from a kill) is cut off the file."""
    if not path.exists():
        return []
    data = path.read_bytes()
    keep = data.rfind(b"\n") + 1
    if keep < len(data):
        with path.open("r+b") as handle:
            handle.truncate(keep)
    records = []
    for number, line in enumerate(data[:keep].splitlines(), start=1):
        if not line.strip():
            continue
        try:
            records.append(EpisodeRecord.from_json(json.loads(line), f"{path}:{number}"))
        except ValueError:
            raise InputError(path, f"line {number}", "one JSON object per line") from None
    return records
