"""The ablation report's files: ``ablations.csv`` and ``ablations.md`` (the paper's tables beside ours, and where
the orderings differ), written from an :class:`~drivenav.analysis.ablation_data.AblationReport`."""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from itertools import pairwise
from pathlib import Path

from drivenav.analysis.ablation_data import (
    FLOOR_GROUPS,
    AblationReport,
    ComputeTable,
    Floors,
    Interval,
    MethodEntry,
    ModelCalls,
    Paired,
    Pictures,
    Runtime,
    SplitEntry,
    Splits,
)
from drivenav.analysis.beyond_report import beyond_section
from drivenav.analysis.compare import Comparison
from drivenav.analysis.counter_columns import decision_columns, step_columns
from drivenav.analysis.paper_tables import (
    PAIRED_REFERENCE,
    TABLE_I,
    TABLE_I_BENCHMARKS,
    TABLE_II,
    TABLE_V,
    TABLE_VI,
    TABLE_VI_MODULES,
    TABLE_VII_PAPER,
    PaperRow,
)
from drivenav.analysis.stats import BOOTSTRAP_RESAMPLES
from drivenav.eval.report import CallCounts
from drivenav.jsonstream import JsonObject

Methods = dict[str, MethodEntry]

# ----------------------------------------------------------------------------------------------- csv


def flatten(entry: JsonObject, prefix: str = "") -> JsonObject:
    """Nested fields joined by dots; an interval ``[lo, hi]`` becomes ``name.lo`` and ``name.hi`` (a CSV row from
    an entry's JSON, so the columns are named as ``ablations.json``'s keys)."""
    flat: JsonObject = {}
    for key, value in entry.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(flatten(value, f"{name}."))
        elif isinstance(value, list):
            flat.update({f"{name}.lo": value[0], f"{name}.hi": value[1]})
        else:
            flat[name] = value
    return flat


def write_csv(report: AblationReport, path: Path) -> None:
    """One row per method with its ``ablations.json`` fields flattened, then its floor groups' columns."""
    rows = [
        {"method": name, **flatten(entry.to_json()), **floor_columns(report.floors, name)}
        for name, entry in report.methods.items()
    ]
    write_rows(rows, path, missing=0)


def write_rows(rows: Sequence[JsonObject], path: Path, missing: object) -> None:
    """``rows`` as a CSV file: every key of any row a column, in order of first use; ``missing`` where a row lacks
    one."""
    fields = list(dict.fromkeys(key for row in rows for key in row))
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields, restval=missing)
        writer.writeheader()
        writer.writerows(rows)


PAIRED_COLUMNS = ("shared", "wins", "losses")
"""The fields of a :class:`~drivenav.analysis.ablation_data.Paired` a floor group's CSV columns show (its reference
is ``floors.reference``)."""


def floor_columns(floors: Floors | None, method: str) -> JsonObject:
    """A method's columns of the floor groups (none without them): ``floors.reference``, then per group its entry
    (``floors.GROUP.spl`` ...) and its wins and losses against the reference (``floors.GROUP.wins`` ...; where the
    reference was run). Cells the method has no value for are blank, never the writer's 0: the reference's own
    wins, a group the method has no record in."""
    if floors is None:
        return {}
    columns: JsonObject = {"floors.reference": floors.reference}
    for group, by_method in floors.groups.items():
        entry = by_method.get(method)
        shape = flatten(next(iter(by_method.values())).to_json())  # the columns the others have
        cells = dict.fromkeys(shape) if entry is None else flatten(entry.to_json())
        if group in floors.paired:
            pair = floors.paired[group].get(method)
            cells.update(
                zip(PAIRED_COLUMNS, (None,) * 3 if pair is None else (pair.shared, pair.wins, pair.losses), strict=True)
            )
        columns.update((f"floors.{group}.{key}", value) for key, value in cells.items())
    return columns


# ----------------------------------------------------------------------------------------------- markdown


def format_markdown(report: AblationReport) -> str:
    """``ablations.md``: the paper's tables with our numbers beside the paper's, failures, ordering differences."""
    sections = [
        _header(report),
        *([_splits(report.splits)] if report.splits else []),
        *([_floors(report.floors)] if report.floors else []),
        _table_i(report.methods, report.paired),
        _table_vi(report.methods),
        _table_v(report.methods),
        _table_ii(report.table_ii),
        *([beyond_section(report)] if report.beyond else []),
        _table_vii(report.runtime),
        _decisions(report.methods),
        _steps(report.methods),
        _failures(report.methods),
        _missed(report.methods),
        _orderings(report),
        _pictures(report.pictures),
    ]
    return "\n\n".join("\n".join(lines) for lines in sections) + "\n"


def _header(report: AblationReport) -> list[str]:
    """What was run: episodes, seed, scenes, step budget, models, commit, and how the intervals are computed."""
    commit = report.commit or "unknown"
    return [
        "# Ablations on the embedded benchmark",
        "",
        f"{report.episodes} episodes, seed {report.seed}, scenes `{report.scenes}`, at most "
        f"{report.max_steps} steps, reasoner `{report.models.reasoner}`, detector "
        f"`{report.models.detector}`, commit {commit}. SR and SPL in %, with 95 % intervals in brackets "
        f"(Wilson score for SR, percentile bootstrap of the mean with {BOOTSTRAP_RESAMPLES} resamples for SPL). "
        "Paper values: HM3D-OVON (DRIVE-Nav, Tables II, V, VI, VII); Table I's on HM3D-OVON, HM3Dv1, HM3Dv2 and "
        "MP3D.",
    ]


def _splits(splits: Splits) -> list[str]:
    """SR and SPL of each method per vocabulary split, as HM3D-OVON reports its validation splits."""
    names = list(splits)
    methods = list(dict.fromkeys(method for by_method in splits.values() for method in by_method))
    lines = [
        "## Per split",
        "",
        "Each method on the episodes of each vocabulary split (HM3D-OVON's val_seen: common categories by name; "
        "val_seen_synonyms: the same categories by a synonym; val_unseen: the other categories by name). "
        "SR % and SPL % with 95 % intervals.",
        "",
        "| method | " + " | ".join(f"{name} SR | {name} SPL" for name in names) + " |",
        "|---|" + "---|---|" * len(names),
    ]
    for method in methods:
        cells = [_split_cells(splits[name].get(method)) for name in names]
        lines.append(f"| `{method}` | " + " | ".join(cells) + " |")
    counts = ", ".join(f"{name} ({_split_size(splits[name])})" for name in names)
    return [*lines, "", f"Episodes per split: {counts}."]


def _split_cells(entry: SplitEntry | None) -> str:
    if entry is None:
        return "- | -"
    return f"{percent(entry.success_rate, entry.sr_ci95)} | {percent(entry.spl, entry.spl_ci95)}"


def _split_size(by_method: dict[str, SplitEntry]) -> int:
    return max(entry.episodes for entry in by_method.values())


def _floors(floors: Floors) -> list[str]:
    """SR and SPL of each method per floor group, one row per group and method (cross-floor episodes in rows of
    their own), with its wins and losses against the reference within the group."""
    reference = floors.reference
    lines = [
        "## Per floor group",
        "",
        "Each method on the episodes of each floor group: one-floor homes (scenes of one storey), same floor (a home "
        "of several storeys, a goal on the start floor) and cross floor (no goal on the start floor: the episode "
        "needs a floor change). Episodes, successes, errors, SR % and SPL % with 95 % intervals as above, and, "
        f"episode by episode against `{reference}` within the group, wins (solved here, not by `{reference}`) and "
        "losses over the episodes both measured.",
        "",
        "| floors | method | episodes | successes | errors | SR % | SPL % | "
        f"wins / losses vs `{reference}` (episodes) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for group, by_method in floors.groups.items():
        for method, entry in by_method.items():
            results, pair = entry.results, floors.paired.get(group, {}).get(method)
            counts = f"{results.episodes} | {entry.successes} | {results.errors}"
            paired = versus(method, reference, pair)
            lines.append(f"| {FLOOR_GROUPS[group]} | `{method}` | {counts} | {_split_cells(results)} | {paired} |")
    sizes = ", ".join(f"{FLOOR_GROUPS[group]} ({floors.size(group)})" for group in floors.groups)
    missing = "" if floors.reference_run else f" `{reference}` was not run."
    return [*lines, "", f"Episodes per floor group: {sizes}.{missing}"]


def versus(method: str, reference: str, pair: Paired | None) -> str:
    """A method's paired cell: ``wins / losses (episodes)`` against the reference, ``reference`` for the reference
    itself, ``-`` where it was not paired."""
    if pair is not None:
        return f"{pair.wins} / {pair.losses} ({pair.shared})"
    return "reference" if method == reference else "-"


def _pictures(pictures: Pictures) -> list[str]:
    lines = ["## Pictures", ""]
    if not pictures.episodes:
        return [*lines, "None drawn (`--pictures 0`, or no episode finished by every method)."]
    lines.append(
        "The same episodes for each method (`drivenav viz` top-down maps: path by segment, decisions, "
        "representative views, detections, goal); Table II episodes first."
    )
    for episode_id, by_method in pictures.episodes.items():
        lines.extend(["", f"Episode `{episode_id}`:", ""])
        lines.append("| " + " | ".join(f"`{m}`" for m in by_method) + " |")
        lines.append("|" + "---|" * len(by_method))
        lines.append("| " + " | ".join(f"![{m}]({path})" for m, path in by_method.items()) + " |")
    if pictures.video:
        lines.extend(
            ["", f"Video (egocentric view beside the map, step by step): [{pictures.video}]({pictures.video})"]
        )
    return lines


def percent(value: float | None, interval: Interval | None) -> str:
    """A rate in % with its 95 % interval in brackets (``n/a`` without a measured episode)."""
    if value is None or interval is None:
        return "n/a"
    return f"{100 * value:.1f} [{100 * interval[0]:.1f}, {100 * interval[1]:.1f}]"


def _sr_spl(entry: MethodEntry) -> str:
    """SR and SPL with their intervals, then the episodes an exception ended."""
    sr, spl = percent(entry.success_rate, entry.sr_ci95), percent(entry.spl, entry.spl_ci95)
    return f"{sr} | {spl} | {entry.errors}"


def _rows_present(rows: Sequence[PaperRow], methods: Mapping[str, object]) -> list[PaperRow]:
    return [row for row in rows if row.method in methods]


def _not_run(lines: list[str], rows: Sequence[PaperRow]) -> list[str]:
    return lines if rows else [lines[0], "", "No method of this table was run."]


def _table_i(methods: Methods, paired: Mapping[str, Paired]) -> list[str]:
    """Every method run: SR, SPL, steps, revisits, paired wins and losses, beside the paper's Table I."""
    papers = {row.method: row.results for row in TABLE_I}
    lines = [
        "## Table I: all methods",
        "",
        "Every method on these episodes: SR and SPL with 95 % intervals, mean steps and revisits per episode, and, "
        f"episode by episode against `{PAIRED_REFERENCE}`, wins (solved here, not by `{PAIRED_REFERENCE}`) and "
        "losses over the episodes both measured. Beside them the paper's Table I, SR / SPL % per benchmark where it "
        "reports the method (ApexNav's as it cites them from ApexNav's own paper); `-`: not reported.",
        "",
        "| method | SR % | SPL % | errors | steps | revisits | wins / losses (episodes) | "
        + " | ".join(f"paper {name}" for name in TABLE_I_BENCHMARKS)
        + " |",
        "|---|---|---|---|---|---|---|" + "---|" * len(TABLE_I_BENCHMARKS),
    ]
    for name, entry in methods.items():
        steps, revisits = _number(entry.avg_steps, "{:.1f}"), _number(entry.avg_revisits, "{:.3f}")
        pair = versus(name, PAIRED_REFERENCE, paired.get(name))
        results = papers.get(name, (None,) * len(TABLE_I_BENCHMARKS))
        cells = " | ".join("-" if r is None else f"{r[0]:.1f} / {r[1]:.1f}" for r in results)
        lines.append(f"| `{name}` | {_sr_spl(entry)} | {steps} | {revisits} | {pair} | {cells} |")
    return lines


def _table_vi(methods: Methods) -> list[str]:
    rows = _rows_present(TABLE_VI, methods)
    lines = [
        "## Table VI: module ablation",
        "",
        f"| {' | '.join(TABLE_VI_MODULES)} | method | SR % | SPL % | errors | paper SR / SPL |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        marks = " | ".join("✓" if on else "" for on in row.modules)
        paper = f"{row.paper[0]:.1f} / {row.paper[1]:.1f}"
        lines.append(f"| {marks} | `{row.method}` | {_sr_spl(methods[row.method])} | {paper} |")
    return _not_run(lines, rows)


def _table_v(methods: Methods) -> list[str]:
    rows = _rows_present(TABLE_V, methods)
    lines = [
        "## Table V: directional-reasoning components",
        "",
        "| method | ours | SR % | SPL % | errors | paper SR / SPL |",
        "|---|---|---|---|---|---|",
    ]
    for row in rows:
        paper = f"{row.paper[0]:.1f} / {row.paper[1]:.1f}"
        lines.append(f"| {row.label} | `{row.method}` | {_sr_spl(methods[row.method])} | {paper} |")
    return _not_run(lines, rows)


def _table_ii(table: Comparison) -> list[str]:
    rows = _rows_present(TABLE_II, table.methods)
    lines = [
        "## Table II: common successful episodes",
        "",
        f"Episodes every method below solved, start-to-goal geodesic distance > {table.min_distance:g} m: "
        f"n = {table.common_episodes}. Lower is better. Revisits: the paper's count (a frontier-selection "
        "segment that travels >= 5 m within 0.5 m of the earlier path); retraced: the same without segments (each "
        "stretch of >= 5 m driven within 0.5 m of the path driven more than 1 m earlier), and its metres.",
        "",
        "| method | ours | avg steps | avg revisits | retraced | retraced m | paper steps | paper revisits |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        common = table.methods[row.method].common
        ours = "- | - | - | -"
        if common:
            retraced = [_number(value, "{:.3f}") for value in (common.avg_retraced_revisits, common.avg_retraced_m)]
            ours = f"{common.avg_steps:.1f} | {common.avg_revisits:.3f} | {' | '.join(retraced)}"
        lines.append(f"| {row.label} | `{row.method}` | {ours} | {row.paper[0]:.1f} | {row.paper[1]:.3f} |")
    return _not_run(lines, rows)


def _table_vii(runtime: Runtime) -> list[str]:
    lines = ["## Table VII: runtime", "", *_compute_rows(runtime.compute)]
    for kind, calls in runtime.model_calls.items():
        lines.append(
            f"| model call: {kind} | {calls.mean_latency_ms:.1f} ms (mean) |"
            f" {calls.calls_per_episode:.2f} per episode{_by_method(calls)} |"
        )
    lines.extend(["", f"Paper (real-world workstation): {TABLE_VII_PAPER}."])
    return lines


def _by_method(calls: ModelCalls) -> str:
    """Each method's calls per episode, when more than one method makes the call (their pooled mean hides them)."""
    if len(calls.by_method) < 2:
        return ""
    return " (" + ", ".join(f"`{method}` {rate:.2f}" for method, rate in sorted(calls.by_method.items())) + ")"


def _compute_rows(compute: ComputeTable | None) -> list[str]:
    header = ["", "| module | latency (median) | invocation |", "|---|---|---|"]
    if compute is None:
        return ["No per-step timings in these runs' traces; model calls only.", *header]
    rows = [
        f"Agent compute per step (models excluded), `{compute.agent}`, every step of its {compute.episodes} "
        f"episodes ({compute.steps} steps, {compute.width}x{compute.height}): median "
        f"{compute.latency.median_ms:.1f} ms, p90 {compute.latency.p90_ms:.1f} ms. Model calls: mean latency per "
        "call over every run above, calls per episode over the runs of the methods that make them (and, where "
        "several do, each one's).",
        *header,
    ]
    for name, module in compute.modules.items():
        latency = "-" if module.latency is None else f"{module.latency.median_ms:.2f} ms"
        count = "" if module.invocations is None else f", {module.invocations} in {compute.steps} steps"
        rows.append(f"| {name} | {latency} | {module.invocation}{count} |")
    return rows


def _number(value: float | None, template: str) -> str:
    return "-" if value is None else template.format(value)


def _explorers(methods: Methods) -> list[str]:
    """The plug-in explorers that made the methods' runs."""
    return [name for entry in methods.values() for name in entry.plugins]


def _decisions(methods: Methods) -> list[str]:
    """The explorers' counters, per-episode means (:mod:`drivenav.analysis.counter_columns`)."""
    columns = decision_columns([entry.decisions for entry in methods.values()], _explorers(methods))
    lines = [
        "## Decisions and direction labels per episode",
        "",
        "Means per episode (model calls: median and mean, the reasoner's questions apart from the image-text "
        "scorer's frames; `-` where the runs cannot tell them apart). Decisions by trigger: the start scan (and every "
        "decision of the 360 deg scanning methods), an inspection event, the followed direction gone, the "
        "planner stuck; a dead end offers the rear range because no direction is left in the forward 240 deg. "
        "ApexNav's decisions by mode (semantic: a TSP over the high-value frontiers when three or more, geometric: "
        "the nearest) and the frontiers it made dormant. `-`: the method's explorer keeps no such counter.",
        "",
        "| method | reasoner calls (median / mean) | scorer calls (median / mean) | "
        + " | ".join(column.title for column in columns)
        + " |",
        "|---|---|---|" + "---|" * len(columns),
    ]
    for name, entry in methods.items():
        cells = " | ".join(column.cell(entry.decisions, entry.episodes - entry.errors) for column in columns)
        lines.append(f"| `{name}` | {_calls(entry.calls)} | {cells} |")
    return lines


def _calls(calls: CallCounts | None) -> str:
    """The reasoner's and the scorer's cells: median / mean calls per episode (``-`` where the runs cannot tell)."""
    known = calls or CallCounts(None, None, None, None)
    reasoner = _median_mean(known.median_reasoner_calls, known.avg_reasoner_calls)
    return f"{reasoner} | {_median_mean(known.median_scorer_calls, known.avg_scorer_calls)}"


def _median_mean(median: float | None, mean: float | None) -> str:
    return f"{_number(median, '{:g}')} / {_number(mean, '{:.1f}')}"


def _steps(methods: Methods) -> list[str]:
    activities = step_columns([entry.decisions for entry in methods.values()], _explorers(methods))
    lines = [
        "## Where the steps go",
        "",
        "Mean steps per episode by activity (`escape`: the local planner's collision recovery) and turn "
        "reversals (a left turn right after a right one or the reverse).",
        "",
        "| method | steps | " + " | ".join(activities) + " | turn reversals |",
        "|---|---|" + "---|" * (len(activities) + 1),
    ]
    for name, entry in methods.items():
        means = entry.decisions
        cells = " | ".join(_number(means.get(f"steps.{key}", 0.0), "{:.1f}") for key in activities)
        steps = _number(entry.avg_steps, "{:.1f}")
        lines.append(f"| `{name}` | {steps} | {cells} | {_number(means.get('turn_reversals', 0.0), '{:.1f}')} |")
    return lines


def _missed(methods: Methods) -> list[str]:
    causes = list(dict.fromkeys(c for entry in methods.values() for c in entry.missed_target_causes))
    lines = [
        "## Missed targets by cause",
        "",
        "`missed_target` episodes (a goal was in view at some step, never reached), by what the agent did with it.",
        "",
        f"| method | missed | {' | '.join(causes)} |",
        "|---|---|" + "---|" * len(causes),
    ]
    for name, entry in methods.items():
        counts = entry.missed_target_causes
        cells = " | ".join(str(counts.get(c, 0)) for c in causes)
        lines.append(f"| `{name}` | {sum(counts.values())} | {cells} |")
    return lines


def _failures(methods: Methods) -> list[str]:
    causes = list(dict.fromkeys(c for entry in methods.values() for c in entry.failure_causes))
    lines = [
        "## Failure causes",
        "",
        f"| method | episodes | failures | {' | '.join(causes)} |",
        "|---|---|---|" + "---|" * len(causes),
    ]
    for name, entry in methods.items():
        counts = entry.failure_causes
        cells = " | ".join(str(counts.get(c, 0)) for c in causes)
        lines.append(f"| `{name}` | {entry.episodes} | {sum(counts.values())} | {cells} |")
    return lines


# ----------------------------------------------------------------------------------------------- orderings


def ordering_differences(paper: dict[str, float], ours: dict[str, float]) -> list[str]:
    """Pairs the paper orders strictly whose order is reversed, or tied, in ours."""
    differences = []
    names = sorted(paper, key=paper.__getitem__)
    for i, low in enumerate(names):
        for high in names[i + 1 :]:
            if paper[low] < paper[high] and ours[low] >= ours[high]:
                relation = "ties" if ours[low] == ours[high] else "is above"
                differences.append(
                    f"`{low}` {relation} `{high}` here ({ours[low]:g} vs {ours[high]:g}; paper {paper[low]:g} "
                    f"vs {paper[high]:g})"
                )
    return differences


def _ordering_line(title: str, paper: dict[str, float], ours: dict[str, float]) -> str:
    if len(ours) < 2:
        return f"- {title}: fewer than two methods with a value here; not compared."
    order = _order_text(paper)
    differences = ordering_differences(paper, ours)
    if not differences:
        return f"- {title}: same ordering as the paper ({order})."
    return f"- {title}: differs from the paper's ordering ({order}): " + "; ".join(differences) + "."


def _order_text(values: dict[str, float]) -> str:
    """Names in ascending order of value, joined by ``<`` (or ``=`` for ties)."""
    names = sorted(values, key=values.__getitem__)
    text = f"`{names[0]}`"
    for previous, name in pairwise(names):
        text += f" {'=' if values[name] == values[previous] else '<'} `{name}`"
    return text


def _metric(rows: Sequence[PaperRow], index: int, ours: dict[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    present = [row for row in rows if row.method in ours]
    return {row.method: row.paper[index] for row in present}, {row.method: ours[row.method] for row in present}


def _shown(values: Mapping[str, float | None], digits: int, scale: float = 1.0) -> dict[str, float]:
    """Values as the tables show them (``scale`` times, rounded), for the methods that have one (a method with no
    measured episode has no rate to order)."""
    return {name: round(scale * value, digits) for name, value in values.items() if value is not None}


def _orderings(report: AblationReport) -> list[str]:
    methods = report.methods
    sr = _shown({name: entry.success_rate for name, entry in methods.items()}, 1, 100.0)
    spl = _shown({name: entry.spl for name, entry in methods.items()}, 1, 100.0)
    common = {name: row.common for name, row in report.table_ii.methods.items() if row.common}
    steps = _shown({name: row.avg_steps for name, row in common.items()}, 1)
    revisits = _shown({name: row.avg_revisits for name, row in common.items()}, 3)
    checks = [
        ("Table VI, SR", TABLE_VI, 0, sr),
        ("Table VI, SPL", TABLE_VI, 1, spl),
        ("Table V, SR", TABLE_V, 0, sr),
        ("Table V, SPL", TABLE_V, 1, spl),
        ("Table II, average steps", TABLE_II, 0, steps),
        ("Table II, average revisits", TABLE_II, 1, revisits),
    ]
    lines = [
        "## Where our orderings differ from the paper's",
        "",
        "Each table's methods ordered by value (ascending), compared pairwise with the paper's ordering. Differences "
        "smaller than the 95 % intervals above are not evidence either way.",
        "",
    ]
    lines.extend(_ordering_line(title, *_metric(rows, index, ours)) for title, rows, index, ours in checks)
    for benchmark in ("HM3Dv1", "HM3Dv2"):
        for index, (metric, ours) in enumerate((("SR", sr), ("SPL", spl))):
            lines.append(_ordering_line(f"Table I ({benchmark}), {metric}", *_table_i_metric(benchmark, index, ours)))
    return lines


def _table_i_metric(benchmark: str, index: int, ours: dict[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    """The paper's Table I values on ``benchmark`` and ours, for the methods with both."""
    column = TABLE_I_BENCHMARKS.index(benchmark)
    paper = {row.method: row.results[column] for row in TABLE_I}
    present = {name: result[index] for name, result in paper.items() if result is not None and name in ours}
    return present, {name: ours[name] for name in present}
