"""The methods beyond the paper in the ablation report: each against the method it builds on, episode by episode.

A method of :data:`~drivenav.methods.METHODS` without a paper table names its ``base`` (``drive-nav-plus``:
``drive-nav``; an ablation row of it: ``drive-nav-plus``). Where both were run, :func:`paired_entry` compares them
on the episodes both finished without an error: SR wins and losses (solved by one and not the other), the mean SPL
difference with its 95 % percentile-bootstrap interval (episodes resampled in pairs), and each one's median
direction decisions per episode. :func:`beyond_table_ii` is Table II's comparison (common successes over 10 m)
over the paper's Table II methods and the methods beyond the paper built directly on one of them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from statistics import median

from drivenav.analysis.compare import Comparison, RunRecords, compare_runs
from drivenav.analysis.stats import bootstrap_mean_interval
from drivenav.eval.records import EpisodeRecord
from drivenav.jsonstream import JsonObject
from drivenav.methods import method_named

Interval = tuple[float, float]


@dataclass(frozen=True)
class PairedEntry:
    """A method beyond the paper against its ``base`` on ``episodes`` paired episodes (module docstring)."""

    base: str
    episodes: int
    sr_wins: int
    sr_losses: int
    spl_delta: float
    spl_delta_ci95: Interval
    median_decisions: float | None
    base_median_decisions: float | None

    def to_json(self) -> JsonObject:
        return {**asdict(self), "spl_delta_ci95": list(self.spl_delta_ci95)}

    @staticmethod
    def from_json(data: JsonObject) -> PairedEntry:
        low, high = data["spl_delta_ci95"]
        return PairedEntry(**{**data, "spl_delta_ci95": (float(low), float(high))})


def direction_decisions(record: EpisodeRecord) -> int | None:
    """The episode's direction decisions (the explorer's ``decisions`` counts summed), None where it keeps none."""
    counters = record.explorer.counters if record.explorer else {}
    decisions = counters.get("decisions")
    return sum(decisions.values()) if isinstance(decisions, dict) else None


def median_decisions(records: list[EpisodeRecord]) -> float | None:
    """The median direction decisions per episode over the records that count them."""
    counts = [count for count in map(direction_decisions, records) if count is not None]
    return float(median(counts)) if counts else None


def paired_entry(runs: RunRecords, name: str, base: str) -> PairedEntry | None:
    """``name`` against ``base`` on the episodes both finished without an error (None without one)."""
    ids = sorted(i for i in set(runs[name]) & set(runs[base]) if not (runs[name][i].is_error or runs[base][i].is_error))
    if not ids:
        return None
    ours, theirs = [runs[name][i] for i in ids], [runs[base][i] for i in ids]
    solved = [(bool(a.success), bool(b.success)) for a, b in zip(ours, theirs, strict=True)]
    deltas = [float(a.spl or 0.0) - float(b.spl or 0.0) for a, b in zip(ours, theirs, strict=True)]
    low, high = bootstrap_mean_interval(deltas)
    return PairedEntry(
        base,
        len(ids),
        sum(a and not b for a, b in solved),
        sum(b and not a for a, b in solved),
        round(sum(deltas) / len(deltas), 6),
        (round(low, 6), round(high, 6)),
        median_decisions(ours),
        median_decisions(theirs),
    )


def paired_entries(runs: RunRecords) -> dict[str, PairedEntry]:
    """Every method beyond the paper that was run with its base, by name."""
    entries = {}
    for name in runs:
        base = _base(name)
        entry = paired_entry(runs, name, base) if base in runs else None
        if entry is not None:
            entries[name] = entry
    return entries


def beyond_table_ii(runs: RunRecords, table_ii: tuple[str, ...]) -> Comparison | None:
    """Table II's comparison over the Table II methods run and the methods beyond the paper built directly on one
    of them (``drive-nav-plus``, not its ablation rows, which the pairing compares); None when none was run."""
    beyond = [name for name in runs if name not in table_ii and _base(name) in table_ii]
    if not beyond:
        return None
    chosen = [name for name in table_ii if name in runs] + beyond
    return compare_runs({name: runs[name] for name in chosen})


def _base(name: str) -> str:
    method = method_named(name)
    return method.base if method is not None else ""
