"""Comparing runs: overall metrics and the paper's Table II subset (episodes every method solves, d0 > 10 m)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from drivenav.eval.records import EpisodeRecord, read_records
from drivenav.eval.report import shown, summarize
from drivenav.eval.rundir import EPISODES_FILE

TABLE_II_MIN_DISTANCE = 10.0  # metres, start-to-goal geodesic distance (paper Sec. V-C)


def load_runs(run_dirs: dict[str, Path]) -> dict[str, dict[str, EpisodeRecord]]:
    """Per method, its finished episode records by episode id."""
    return {name: {r.episode_id: r for r in read_records(d / EPISODES_FILE)} for name, d in run_dirs.items()}


def shared_ids(runs: dict[str, dict[str, EpisodeRecord]]) -> set[str]:
    """Episode ids every run has a record of, for the same episode (same scene and target text in every run: runs
    over other episode files reuse ids such as ``0``)."""
    if not runs:
        return set()
    ids = set.intersection(*(set(records) for records in runs.values()))
    return {i for i in ids if len({(r[i].scene_id, r[i].object_category) for r in runs.values()}) == 1}


def common_successes(runs: dict[str, dict[str, EpisodeRecord]], min_distance: float) -> list[str]:
    """Episode ids that every method solved and whose geodesic distance exceeds ``min_distance``."""
    ids = shared_ids(runs)
    first = next(iter(runs.values()), {})
    return sorted(
        i for i in ids if all(runs[m][i].success for m in runs) and (first[i].geodesic_distance or 0.0) > min_distance
    )


def compare(run_dirs: dict[str, Path], min_distance: float = TABLE_II_MIN_DISTANCE) -> dict[str, Any]:
    """Overall summaries and the common-success subset's average steps and revisits per method."""
    return compare_runs(load_runs(run_dirs), min_distance)


def compare_runs(
    runs: dict[str, dict[str, EpisodeRecord]], min_distance: float = TABLE_II_MIN_DISTANCE
) -> dict[str, Any]:
    """:func:`compare` on records already loaded."""
    common = common_successes(runs, min_distance)
    table = {}
    for name, records in runs.items():
        subset = [records[i] for i in common]
        table[name] = {
            "overall": summarize(list(records.values())).to_json(),
            "common": summarize(subset).to_json() if subset else None,
        }
    return {
        "min_distance": min_distance,
        "shared_episodes": len(shared_ids(runs)),
        "common_episodes": len(common),
        "methods": table,
    }


def format_comparison(result: dict[str, Any]) -> str:
    """The comparison as a plain-text table."""
    header = (
        f"{'method':<20} {'episodes':>8} {'errors':>6} {'SR %':>6} {'SPL %':>6} {'steps':>7} {'revisits':>8}"
        f" | common (n={result['common_episodes']}, d0 > {result['min_distance']:g} m): {'steps':>7} {'revisits':>8}"
    )
    lines = [header, "-" * len(header)]
    for name, row in result["methods"].items():
        overall, common = row["overall"], row["common"]
        tail = f"{common['avg_steps']:>7.1f} {common['avg_revisits']:>8.3f}" if common else f"{'-':>7} {'-':>8}"
        rates = [shown(overall[k], "{:>6.1f}", 100.0).rjust(6) for k in ("success_rate", "spl")]
        lines.append(
            f"{name:<20} {overall['episodes']:>8} {overall['errors']:>6} {' '.join(rates)}"
            f" {shown(overall['avg_steps'], '{:>7.1f}'):>7} {shown(overall['avg_revisits'], '{:>8.3f}'):>8}"
            f" | {'':>38}{tail}"
        )
    return "\n".join(lines)
