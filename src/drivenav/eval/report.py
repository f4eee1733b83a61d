"""Run summaries (``summary.json``) and the readable table printed after an evaluation.

Rates and averages over no episode (or over a measure the world could not take) are ``null`` in JSON and
``n/a`` in the table. Episodes that an exception ended are counted in ``errors`` and left out of nothing else:
they are failures of the run, reported as such, never navigation failures.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from statistics import median

from drivenav.eval.records import EpisodeRecord
from drivenav.jsonstream import JsonObject


def mean(records: Sequence[EpisodeRecord], value: Callable[[EpisodeRecord], float | None]) -> float | None:
    """The mean of a per-episode value over the episodes that have it (None when none has)."""
    values = [float(v) for v in map(value, records) if v is not None]
    return sum(values) / len(values) if values else None


def _rounded(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


def _median(values: Sequence[int]) -> float | None:
    return median(values) if values else None


def _average(values: Sequence[int]) -> float | None:
    return _rounded(sum(values) / len(values), 3) if values else None


@dataclass(frozen=True)
class CallCounts:
    """Model calls per episode by model (:func:`~drivenav.agent.base.split_calls`): the reasoner's and the image-text
    scorer's, mean and median over the records that tell them apart (None where none does: a record written without
    ``vlm_calls_by_kind``). ``avg_vlm_calls`` adds the two, though a scorer call costs milliseconds and a reasoner
    call seconds."""

    avg_reasoner_calls: float | None
    median_reasoner_calls: float | None
    avg_scorer_calls: float | None
    median_scorer_calls: float | None

    @staticmethod
    def of(records: Sequence[EpisodeRecord]) -> CallCounts:
        splits = [split for split in (r.calls for r in records) if split is not None]
        reasoner, scorer = [s.reasoner for s in splits], [s.scorer for s in splits]
        return CallCounts(_average(reasoner), _median(reasoner), _average(scorer), _median(scorer))

    @staticmethod
    def from_json(data: JsonObject) -> CallCounts | None:
        """The counts among ``data``'s keys (a summary's, a method's), or None where it was written before them."""
        if CALL_KEYS[0] not in data:
            return None
        return CallCounts(*(data[key] for key in CALL_KEYS))

    @staticmethod
    def without(data: JsonObject) -> JsonObject:
        """``data`` less the counts' keys."""
        return {key: value for key, value in data.items() if key not in CALL_KEYS}


CALL_COLUMNS = ("reasoner calls", "scorer calls")
"""The model-call columns of every table (the report's pages, ``compare``): the reasoner's and the image-text
scorer's, never added together."""

CALL_KEYS = tuple(item.name for item in fields(CallCounts))
"""The keys :class:`CallCounts` adds, flat, to ``summary.json`` and to each method of ``ablations.json``."""


def with_calls(data: JsonObject) -> JsonObject:
    """An object whose ``calls`` (a :class:`CallCounts` as a dictionary, or None) is written flat at its end, or not
    at all where it is None (files written before it keep their bytes)."""
    calls = data.pop("calls")
    return data if calls is None else {**data, **calls}


RATE_KEYS = ("episodes_per_hour", "frames_per_second")
"""An eval's rate in ``summary.json`` (:class:`Throughput`), absent from a summary of records read back."""


@dataclass(frozen=True)
class Summary:
    """The ``summary.json`` fields. ``episodes_per_hour`` and ``frames_per_second`` are the eval's own rate, over
    the wall time of its last session that ran episodes (:class:`Throughput`); None where no eval timed them (a
    summary of records read back)."""

    episodes: int
    success_rate: float | None
    spl: float | None
    avg_steps: float | None
    avg_revisits: float | None
    avg_retraced_revisits: float | None
    avg_retraced_m: float | None
    avg_path_length: float | None
    avg_geodesic_distance: float | None
    avg_distance_to_goal: float | None
    avg_collisions: float | None
    avg_vlm_calls: float | None
    median_vlm_calls: float | None
    vlm_fallbacks: int
    errors: int
    stop_reasons: dict[str, int] = field(default_factory=dict)
    calls: CallCounts | None = None
    episodes_per_hour: float | None = None
    frames_per_second: float | None = None

    def to_json(self) -> JsonObject:
        """The ``summary.json`` object (keys in field order, the calls by model flat at the end; the rate only where
        an eval timed one)."""
        data = with_calls(asdict(self))
        return {key: value for key, value in data.items() if key not in RATE_KEYS or value is not None}

    @staticmethod
    def from_json(data: JsonObject) -> Summary:
        """A summary as :meth:`to_json` wrote it, with or without the calls by model (a missing or unknown key is a
        :class:`TypeError`)."""
        return Summary(**CallCounts.without(data), calls=CallCounts.from_json(data))


@dataclass(frozen=True)
class Throughput:
    """An eval session's rate (issue 61): ``episodes`` finished in ``wall_s`` seconds of it (start-up included),
    whose agents took ``frames`` steps (a frame rendered and grounded each)."""

    episodes: int
    frames: int
    wall_s: float

    @property
    def episodes_per_hour(self) -> float | None:
        return round(3600.0 * self.episodes / self.wall_s, 1) if self.episodes and self.wall_s > 0 else None

    @property
    def frames_per_second(self) -> float | None:
        return round(self.frames / self.wall_s, 2) if self.episodes and self.wall_s > 0 else None

    def line(self) -> str:
        """The rate as the progress bar shows it."""
        eph, fps = self.episodes_per_hour, self.frames_per_second
        return "" if eph is None or fps is None else f"{eph:.0f} ep/h, {fps:.1f} frames/s"


def summarize(records: Sequence[EpisodeRecord], throughput: Throughput | None = None) -> Summary:
    """Aggregate episode records into a :class:`Summary` (with an eval session's ``throughput`` when it timed one)."""
    return Summary(
        episodes=len(records),
        success_rate=_rounded(mean(records, lambda r: r.success), 6),
        spl=_rounded(mean(records, lambda r: r.spl), 6),
        avg_steps=_rounded(mean(records, lambda r: r.steps), 3),
        avg_revisits=_rounded(mean(records, lambda r: r.revisits), 4),
        avg_retraced_revisits=_rounded(mean(records, lambda r: r.retraced_revisits), 4),
        avg_retraced_m=_rounded(mean(records, lambda r: r.retraced_m), 3),
        avg_path_length=_rounded(mean(records, lambda r: r.path_length), 3),
        avg_geodesic_distance=_rounded(mean(records, lambda r: r.geodesic_distance), 3),
        avg_distance_to_goal=_rounded(mean(records, lambda r: r.distance_to_goal), 3),
        avg_collisions=_rounded(mean(records, lambda r: r.collisions), 3),
        avg_vlm_calls=_rounded(mean(records, lambda r: r.vlm_calls), 3),
        median_vlm_calls=_median([r.vlm_calls for r in records]),
        vlm_fallbacks=sum(r.stats.vlm_fallbacks for r in records),
        errors=sum(r.is_error for r in records),
        stop_reasons=dict(sorted(Counter(r.stop_reason for r in records).items())),
        calls=CallCounts.of(records),
        episodes_per_hour=throughput.episodes_per_hour if throughput is not None else None,
        frames_per_second=throughput.frames_per_second if throughput is not None else None,
    )


def rate_kept(summary: Summary, earlier: Path) -> Summary:
    """``summary`` with the rate of the summary written at ``earlier`` by the session that ran the episodes (a
    rerun with nothing left to run times nothing); an earlier summary that cannot be read keeps none."""
    try:
        data = json.loads(earlier.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return summary
    rates = [
        float(r) for key in RATE_KEYS if isinstance(r := _key(data, key), (int, float)) and not isinstance(r, bool)
    ]
    if len(rates) != len(RATE_KEYS):
        return summary
    return replace(summary, episodes_per_hour=rates[0], frames_per_second=rates[1])


def _key(data: object, key: str) -> object:
    return data.get(key) if isinstance(data, dict) else None


def shown(value: float | None, template: str, scale: float = 1.0) -> str:
    """A value through ``template`` (e.g. ``"{:.1f} %"``), or ``n/a`` where there is none."""
    return "n/a" if value is None else template.format(scale * value)


def call_means(calls: CallCounts | None) -> tuple[float | None, float | None]:
    """Reasoner and scorer calls per episode (None where the records cannot tell them apart)."""
    return (None, None) if calls is None else (calls.avg_reasoner_calls, calls.avg_scorer_calls)


def format_table(summary: Summary, title: str = "") -> str:
    """A plain-text table of a summary, for the terminal (model calls in all, then the reasoner's and the scorer's)."""
    rows = [
        ("episodes", f"{summary.episodes}"),
        ("success rate", shown(summary.success_rate, "{:.1f} %", 100.0)),
        ("SPL", shown(summary.spl, "{:.1f} %", 100.0)),
        ("avg steps", shown(summary.avg_steps, "{:.1f}")),
        ("avg path length", shown(summary.avg_path_length, "{:.2f} m")),
        ("avg geodesic distance", shown(summary.avg_geodesic_distance, "{:.2f} m")),
        ("avg distance to goal", shown(summary.avg_distance_to_goal, "{:.2f} m")),
        ("avg revisits", shown(summary.avg_revisits, "{:.3f}")),
        ("avg retraced stretches", shown(summary.avg_retraced_revisits, "{:.3f}")),
        ("avg collisions", shown(summary.avg_collisions, "{:.2f}")),
        ("avg model calls", shown(summary.avg_vlm_calls, "{:.2f}")),
        *(
            (f"avg {name}", shown(value, "{:.2f}"))
            for name, value in zip(CALL_COLUMNS, call_means(summary.calls), strict=True)
        ),
        ("VLM fallbacks", f"{summary.vlm_fallbacks}"),
        ("errors", f"{summary.errors}"),
        ("stop reasons", ", ".join(f"{k}: {v}" for k, v in summary.stop_reasons.items()) or "-"),
        ("episodes per hour", shown(summary.episodes_per_hour, "{:.0f}")),
        ("frames per second", shown(summary.frames_per_second, "{:.1f}")),
    ]
    width = max(len(name) for name, _ in rows)
    lines = [title] if title else []
    lines.append("-" * (width + 24))
    lines.extend(f"{name:<{width}}  {value}" for name, value in rows)
    lines.append("-" * (width + 24))
    return "\n".join(lines)
