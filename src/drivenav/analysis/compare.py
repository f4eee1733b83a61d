"""Comparing runs: overall metrics and the paper's Table II subset (episodes every method solves, d0 > 10 m).

:func:`compare` returns a :class:`Comparison`; its :meth:`~Comparison.to_json` is what ``drivenav compare --json``
prints and what ``ablations.json`` holds under ``table_ii``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from drivenav.eval.records import EpisodeRecord
from drivenav.eval.report import CALL_COLUMNS, Summary, call_means, shown, summarize
from drivenav.eval.rundir import RunContents, read_run
from drivenav.jsonstream import JsonObject

TABLE_II_MIN_DISTANCE = 10.0  # metres, start-to-goal geodesic distance (paper Sec. V-C)

RunRecords = dict[str, dict[str, EpisodeRecord]]
"""Per method, its finished episode records by episode id."""


def load_runs(run_dirs: dict[str, Path]) -> RunRecords:
    """Per method, its finished episode records by episode id, each run checked as a resume checks it
    (:func:`~drivenav.eval.rundir.read_run`)."""
    return records_by_id({name: read_run(d) for name, d in run_dirs.items()})


def records_by_id(contents: Mapping[str, RunContents]) -> RunRecords:
    """Per method, the records of its run (read by :func:`~drivenav.eval.rundir.read_run`) by episode id."""
    return {name: {r.episode_id: r for r in run.records} for name, run in contents.items()}


def shared_ids(runs: RunRecords) -> set[str]:
    """Episode ids every run has a record of, for the same episode (same scene and target text in every run: runs
    over other episode files reuse ids such as ``0``)."""
    if not runs:
        return set()
    ids = set.intersection(*(set(records) for records in runs.values()))
    return {i for i in ids if len({(r[i].scene_id, r[i].object_category) for r in runs.values()}) == 1}


def common_successes(runs: RunRecords, min_distance: float) -> list[str]:
    """Episode ids that every method solved and whose geodesic distance exceeds ``min_distance``."""
    ids = shared_ids(runs)
    first = next(iter(runs.values()), {})
    return sorted(
        i for i in ids if all(runs[m][i].success for m in runs) and (first[i].geodesic_distance or 0.0) > min_distance
    )


@dataclass(frozen=True)
class ComparedMethod:
    """One method of a comparison: its summary over all its episodes, and over the common-success subset (None
    when that subset is empty)."""

    overall: Summary
    common: Summary | None

    def to_json(self) -> JsonObject:
        return {"overall": self.overall.to_json(), "common": None if self.common is None else self.common.to_json()}

    @staticmethod
    def from_json(data: JsonObject) -> ComparedMethod:
        common = data["common"]
        return ComparedMethod(Summary.from_json(data["overall"]), None if common is None else Summary.from_json(common))


@dataclass(frozen=True)
class Comparison:
    """Runs compared (paper Table II): how many episodes they share, how many of those every method solved over
    ``min_distance`` metres, and each method's summaries."""

    min_distance: float
    shared_episodes: int
    common_episodes: int
    methods: dict[str, ComparedMethod]

    def to_json(self) -> JsonObject:
        """The JSON object of ``drivenav compare --json`` (and ``ablations.json``'s ``table_ii``)."""
        return {
            "min_distance": self.min_distance,
            "shared_episodes": self.shared_episodes,
            "common_episodes": self.common_episodes,
            "methods": {name: method.to_json() for name, method in self.methods.items()},
        }

    @staticmethod
    def from_json(data: JsonObject) -> Comparison:
        """A comparison as :meth:`to_json` wrote it (a missing key is a :class:`KeyError`)."""
        methods = {name: ComparedMethod.from_json(method) for name, method in data["methods"].items()}
        return Comparison(data["min_distance"], data["shared_episodes"], data["common_episodes"], methods)


def compare(run_dirs: dict[str, Path], min_distance: float = TABLE_II_MIN_DISTANCE) -> Comparison:
    """Overall summaries and the common-success subset's average steps and revisits per method."""
    return compare_runs(load_runs(run_dirs), min_distance)


def compare_runs(runs: RunRecords, min_distance: float = TABLE_II_MIN_DISTANCE) -> Comparison:
    """:func:`compare` on records already loaded."""
    common = common_successes(runs, min_distance)
    table = {}
    for name, records in runs.items():
        subset = [records[i] for i in common]
        table[name] = ComparedMethod(summarize(list(records.values())), summarize(subset) if subset else None)
    return Comparison(min_distance, len(shared_ids(runs)), len(common), table)


def format_comparison(result: Comparison) -> str:
    """The comparison as a plain-text table (model calls per episode by model: the reasoner's, the scorer's)."""
    calls = " ".join(CALL_COLUMNS)
    header = (
        f"{'method':<20} {'episodes':>8} {'errors':>6} {'SR %':>6} {'SPL %':>6} {'steps':>7} {'revisits':>8} {calls}"
        f" | common (n={result.common_episodes}, d0 > {result.min_distance:g} m): {'steps':>7} {'revisits':>8}"
    )
    lines = [header, "-" * len(header)]
    for name, row in result.methods.items():
        overall, common = row.overall, row.common
        tail = f"{common.avg_steps:>7.1f} {common.avg_revisits:>8.3f}" if common else f"{'-':>7} {'-':>8}"
        rates = [shown(value, "{:>6.1f}", 100.0).rjust(6) for value in (overall.success_rate, overall.spl)]
        means = call_means(overall.calls)
        per_model = " ".join(
            shown(value, "{:.2f}").rjust(len(column)) for column, value in zip(CALL_COLUMNS, means, strict=True)
        )
        lines.append(
            f"{name:<20} {overall.episodes:>8} {overall.errors:>6} {' '.join(rates)}"
            f" {shown(overall.avg_steps, '{:>7.1f}'):>7} {shown(overall.avg_revisits, '{:>8.3f}'):>8} {per_model}"
            f" | {'':>38}{tail}"
        )
    return "\n".join(lines)
