"""``drivenav compare``'s floor groups: where the runs' episodes carry ``info["cross_floor"]`` (benchmark v3), each
run per floor group (one-floor homes, same floor, cross floor) with SR and SPL and their 95 % intervals, and its
wins and losses against a reference run within each group, as the ablation report's floor groups
(:func:`drivenav.analysis.ablations.floor_entries`). Each run's episodes are its own copy of them (a run over
another episode file has its own groups)."""

from __future__ import annotations

from pathlib import Path

from drivenav.analysis.ablation_data import FLOOR_GROUPS, Floors
from drivenav.analysis.ablation_report import percent, versus
from drivenav.analysis.ablations import floor_entries, floor_groups
from drivenav.analysis.compare import Comparison, compare_runs, format_comparison, records_by_id
from drivenav.eval.rundir import read_run
from drivenav.jsonstream import JsonObject


def compare_with_floors(
    run_dirs: dict[str, Path], min_distance: float, reference: str
) -> tuple[Comparison, Floors | None]:
    """The runs' comparison (:func:`~drivenav.analysis.compare.compare`) and their floor groups paired with the
    run named ``reference`` (None where no run's episodes carry floor information)."""
    contents = {name: read_run(run_dir) for name, run_dir in run_dirs.items()}
    runs = records_by_id(contents)
    groups = {name: floor_groups(run.episodes or ()) for name, run in contents.items()}
    return compare_runs(runs, min_distance), floor_entries(runs, groups, reference)


def comparison_json(comparison: Comparison, floors: Floors | None) -> JsonObject:
    """What ``drivenav compare --json`` prints: the comparison's object, with ``floors`` only where there are
    floor groups."""
    return comparison.to_json() | ({} if floors is None else {"floors": floors.to_json()})


def format_compare(comparison: Comparison, floors: Floors | None) -> str:
    """What ``drivenav compare`` prints: the comparison's table, then the floor groups' where there are some."""
    table = format_comparison(comparison)
    return table if floors is None else f"{table}\n\n{format_floors(floors)}"


def format_floors(floors: Floors) -> str:
    """The floor groups as a plain-text table: one row per group and run (names of any length: a floors-off
    variant's is long)."""
    width = max(20, *(len(name) for by_method in floors.groups.values() for name in by_method))
    header = (
        f"{'floors':<16} {'method':<{width}} {'episodes':>8} {'successes':>9} {'errors':>6} {'SR % [95 %]':<21} "
        f"{'SPL % [95 %]':<21} wins / losses vs {floors.reference} "
        + ("(episodes)" if floors.reference_run else "(not run)")
    )
    lines = [header, "-" * len(header)]
    for group, by_method in floors.groups.items():
        for name, entry in by_method.items():
            results, pair = entry.results, floors.paired.get(group, {}).get(name)
            rates = [percent(results.success_rate, results.sr_ci95), percent(results.spl, results.spl_ci95)]
            lines.append(
                f"{FLOOR_GROUPS[group]:<16} {name:<{width}} {results.episodes:>8} {entry.successes:>9} "
                f"{results.errors:>6} {rates[0]:<21} {rates[1]:<21} {versus(name, floors.reference, pair)}"
            )
    return "\n".join(lines)
