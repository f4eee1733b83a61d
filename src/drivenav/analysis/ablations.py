"""The paper's ablation tables (II, V, VI, VII) on the embedded benchmark: running the methods and aggregating.

``drivenav bench ablations`` runs every method once through :func:`drivenav.eval.runner.evaluate` into
``DIR/runs/<method>/`` (resumable) and writes ``DIR/ablations.json``, ``DIR/ablations.md`` and ``DIR/ablations.csv``
(:mod:`drivenav.analysis.ablation_report`), from one :class:`~drivenav.analysis.ablation_data.AblationReport`. The
benchmark is :mod:`drivenav.benchmarks.benchmark`; the paper's numbers, for comparison only, are
:mod:`drivenav.analysis.paper_tables`. Pictures come from a :class:`PictureMaker` the caller passes in (the application
passes :func:`drivenav.viz.run_pictures.render_pictures`): eval draws nothing itself.
"""

from __future__ import annotations

import json
import math
from collections import Counter, defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Protocol, TypeVar

from drivenav.agent.explorers import BUILT_IN_EXPLORERS
from drivenav.analysis.ablation_data import (
    CROSS_FLOOR,
    FLOOR_GROUPS,
    ONE_FLOOR,
    SAME_FLOOR,
    AblationReport,
    ComputeTable,
    Floors,
    GroupEntry,
    Interval,
    MethodEntry,
    ModelCalls,
    Paired,
    Pictures,
    ReportModels,
    Runtime,
    SplitEntry,
    Splits,
)
from drivenav.analysis.ablation_report import format_markdown, write_csv
from drivenav.analysis.beyond import beyond_table_ii, paired_entries
from drivenav.analysis.compare import RunRecords, compare_runs, load_runs, shared_ids
from drivenav.analysis.paper_tables import PAIRED_REFERENCE, TABLE_II_METHODS
from drivenav.analysis.stats import bootstrap_mean_interval, wilson_interval
from drivenav.benchmarks.ovon_episodes import SPLITS, episode_splits
from drivenav.episode import Episode
from drivenav.errors import InputError
from drivenav.eval.episodes import load_episodes, save_episodes
from drivenav.eval.executor import Executor
from drivenav.eval.provenance import git_commit
from drivenav.eval.records import ERROR, MISSED_CAUSES, EpisodeRecord, missed_cause
from drivenav.eval.report import summarize
from drivenav.eval.run_info import world_json
from drivenav.eval.rundir import EPISODES_COPY, trace_path
from drivenav.eval.runner import RunSpec, evaluate
from drivenav.eval.timings import runtime_table, traced_steps
from drivenav.eval.trace import read_trace
from drivenav.methods import agent_names, method_named
from drivenav.types import SimConfig

FAILURE_CAUSES = ("false_positive_stop", "missed_target", "timeout", "no_frontier", "target_never_seen")
RUNS_DIR = "runs"
FLOOR_INFO = "cross_floor"
"""The ``info`` key of an episode in a home of several storeys: whether it needs a floor change
(:func:`drivenav.benchmarks.generate.floor_info`)."""

RunGroups = Mapping[str, Mapping[str, str]]
"""Per method, the groups of its episodes (episode id -> group name)."""
_Entry = TypeVar("_Entry")


class PictureMaker(Protocol):
    """Draws the report's pictures: ``count`` episodes (ids from ``order``) through the methods of ``dirs`` (their
    run directories, Table II methods first; their records: ``runs``) into ``out``."""

    def __call__(
        self, dirs: dict[str, Path], runs: RunRecords, order: Sequence[str], count: int, out: Path
    ) -> Pictures: ...


def parse_methods(text: str) -> list[str]:
    """Agent names from ``--methods a,b,...`` (duplicates dropped, order kept); a plug-in's entry of methods that
    cannot be loaded is its one line here, before any run."""
    methods = list(dict.fromkeys(name.strip() for name in text.split(",") if name.strip()))
    known = agent_names()
    for name in methods or [text]:
        if name not in known:
            raise InputError("command line", "--methods", f"comma-separated agent names ({', '.join(known)})", name)
        method_named(name)
    return methods


# ----------------------------------------------------------------------------------------------- running


def run_methods(
    episodes: list[Episode], specs: Sequence[RunSpec], out: Path, executor: Executor | None = None
) -> dict[str, Path]:
    """Each method's run through :func:`evaluate` into ``out/runs/<method>/`` (finished episodes are skipped)."""
    _check_episode_set(episodes, out / EPISODES_COPY)
    executor = executor or Executor()
    dirs = {}
    with executor.session():
        for spec in specs:
            run_dir = out / RUNS_DIR / spec.agent
            evaluate(episodes, spec, run_dir, executor)
            dirs[spec.agent] = run_dir
    return dirs


def _check_episode_set(episodes: list[Episode], copy: Path) -> None:
    """A rerun must use the episodes the directory was started with (its tables cover exactly those)."""
    if not copy.exists():
        save_episodes(episodes, copy)
        return
    previous = [e.episode_id for e in load_episodes(copy)]
    if previous != [e.episode_id for e in episodes]:
        expected = f"the {len(previous)} episodes this directory was started with (same --episodes/--seed/--scenes)"
        raise InputError(copy, "--episodes", expected, f"{len(episodes)} episodes")


# ----------------------------------------------------------------------------------------------- aggregation


def method_entry(records: list[EpisodeRecord]) -> MethodEntry:
    """One method's ``ablations.json`` entry: SR / SPL with 95 % intervals, steps, revisits, calls, failures and
    errors (episodes an exception ended: counted apart, never as navigation failures)."""
    summary = summarize(records)
    measured = [r for r in records if r.success is not None]
    return MethodEntry(
        episodes=summary.episodes,
        errors=summary.errors,
        success_rate=summary.success_rate,
        spl=summary.spl,
        avg_steps=summary.avg_steps,
        avg_revisits=summary.avg_revisits,
        sr_ci95=_rounded(wilson_interval(successes(measured), len(measured))) if measured else None,
        spl_ci95=_rounded(bootstrap_mean_interval(_spls_by_episode(measured))) if measured else None,
        avg_retraced_revisits=summary.avg_retraced_revisits,
        vlm_calls=summary.avg_vlm_calls,
        median_vlm_calls=summary.median_vlm_calls,
        failure_causes=failure_counts(records),
        missed_target_causes=missed_counts(records),
        decisions=decision_means(records),
        plugins=tuple(sorted({r.explorer.name for r in records if r.explorer} - set(BUILT_IN_EXPLORERS))),
        calls=summary.calls,
    )


def successes(records: list[EpisodeRecord]) -> int:
    """The episodes solved."""
    return sum(bool(r.success) for r in records)


def missed_counts(records: list[EpisodeRecord]) -> dict[str, int]:
    """``missed_target`` episodes by :func:`~drivenav.eval.records.missed_cause`."""
    counts = Counter(missed_cause(r) for r in records if r.failure_cause == "missed_target")
    return {cause: counts.get(cause, 0) for cause in MISSED_CAUSES}


def decision_means(records: list[EpisodeRecord]) -> dict[str, float | None]:
    """Per-episode means of the body's counters (:class:`~drivenav.agent.base.BodyCounters`) and the explorer's
    (:class:`~drivenav.agent.base.ExplorerCounters`); counts by kind under ``NAME.KIND`` with their sum under ``NAME``
    (``decisions.scan``, ``decisions``), and steps by activity under ``steps.ACTIVITY``. A mean whose sum leaves
    the floats' range (a plug-in's counters near 1e308) is None, written as ``null``: ``ablations.json`` stays
    JSON, which has no ``Infinity``."""
    started = [r for r in records if not r.is_error]
    totals: defaultdict[str, float] = defaultdict(float)
    for record in started:
        body = record.body
        for key, count in [*asdict(body).items(), *((f"steps.{k}", v) for k, v in body.steps_by_activity.items())]:
            if isinstance(count, int):
                totals[key] += count
        for name, value in (record.explorer.counters if record.explorer else {}).items():
            for key, count in value.items() if isinstance(value, dict) else ():
                totals[f"{name}.{key}"] += count
            totals[name] += sum(value.values()) if isinstance(value, dict) else value
    return {key: _finite(round(value / max(len(started), 1), 3)) for key, value in sorted(totals.items())}


def _finite(value: float) -> float | None:
    """``value``, or None where it is not a finite number (a sum that overflowed)."""
    return value if math.isfinite(value) else None


def _spls_by_episode(records: list[EpisodeRecord]) -> list[float]:
    """The SPLs in episode-id order: the bootstrap resamples by position, so records in completion order (which
    depends on the workers) would move its interval from run to run."""
    return [float(r.spl or 0.0) for r in sorted(records, key=lambda r: r.episode_id)]


def _rounded(interval: Interval) -> Interval:
    return round(interval[0], 6), round(interval[1], 6)


def failure_counts(records: list[EpisodeRecord]) -> dict[str, int]:
    """Failed episodes by cause (every known cause listed, then any other cause found)."""
    counts = Counter(r.failure_cause or "unknown" for r in records if not r.success and r.failure_cause != ERROR)
    return {cause: counts.pop(cause, 0) for cause in FAILURE_CAUSES} | dict(sorted(counts.items()))


def model_call_latency(runs: RunRecords) -> dict[str, ModelCalls]:
    """Per model-call kind: mean latency per call, calls per episode over the runs that make such calls, and calls
    per episode of each of those runs."""
    calls: Counter[str] = Counter()
    latency: Counter[str] = Counter()
    episodes: Counter[str] = Counter()
    by_method: dict[str, dict[str, float]] = {}
    for method, records in runs.items():
        run_calls: Counter[str] = Counter()
        for record in records.values():
            run_calls.update(record.stats.vlm_calls_by_kind)
            latency.update(record.stats.vlm_latency_ms)
        calls.update(run_calls)
        for kind, count in run_calls.items():
            if count:
                episodes[kind] += len(records)
                by_method.setdefault(kind, {})[method] = round(count / len(records), 3)
    return {
        kind: ModelCalls(count, round(count / episodes[kind], 3), round(latency[kind] / count, 3), by_method[kind])
        for kind, count in sorted(calls.items())
        if count
    }


RUNTIME_METHOD = "drive-nav"


def measure_runtime(runs: RunRecords, dirs: dict[str, Path]) -> Runtime:
    """Table VII from the runs themselves: per-step module timings saved in the traces of ``drive-nav`` (else
    the first method whose traces have them), model-call latency over every run. ``compute`` is None when no
    trace has timings."""
    sim = SimConfig()
    for method in sorted(dirs, key=lambda name: name != RUNTIME_METHOD):
        read = (read_trace(trace_path(dirs[method], episode_id)) for episode_id in runs[method])
        steps, decisions, episodes = traced_steps(trace for trace in read if trace is not None)
        if steps:
            compute = runtime_table(steps, decisions, episodes, method, sim.width, sim.height)
            return Runtime(ComputeTable.from_json(compute), model_call_latency(runs))
    return Runtime(None, model_call_latency(runs))


def paired_outcomes(runs: RunRecords, reference: str = PAIRED_REFERENCE) -> dict[str, Paired]:
    """Each other method against ``reference`` episode by episode (those both measured: the same episode, no error
    in either): wins (solved here, not by the reference) and losses; empty without the reference."""
    if reference not in runs:
        return {}
    paired = {}
    for name, records in runs.items():
        if name == reference:
            continue
        both = shared_ids({reference: runs[reference], name: records})
        measured = [i for i in sorted(both) if not (records[i].is_error or runs[reference][i].is_error)]
        won = [bool(records[i].success) for i in measured]
        theirs = [bool(runs[reference][i].success) for i in measured]
        wins = sum(a and not b for a, b in zip(won, theirs, strict=True))
        losses = sum(b and not a for a, b in zip(won, theirs, strict=True))
        paired[name] = Paired(reference, len(measured), wins, losses)
    return paired


def grouped_runs(runs: RunRecords, groups: RunGroups, known: Sequence[str] = ()) -> dict[str, RunRecords]:
    """The runs cut into groups of episodes (``groups``: per method, its episodes' groups), the ``known`` groups
    first in their order, then any other by name; a method without a record in a group is left out of it, and a
    group without any record too. Records keep their order (a mean's rounding depends on it)."""
    names = {group for name in runs for group in groups.get(name, {}).values()}
    table: dict[str, RunRecords] = {}
    for group in sorted(names, key=lambda name: (known.index(name) if name in known else len(known), name)):
        cut = {name: _in_group(records, groups.get(name, {}), group) for name, records in runs.items()}
        found = {name: records for name, records in cut.items() if records}
        if found:
            table[group] = found
    return table


def _in_group(records: dict[str, EpisodeRecord], groups: Mapping[str, str], group: str) -> dict[str, EpisodeRecord]:
    return {episode_id: r for episode_id, r in records.items() if groups.get(episode_id) == group}


def split_entries(runs: RunRecords, splits: Mapping[str, str]) -> Splits:
    """Per split (HM3D-OVON's first, then any other by name), each method over its records of the split's
    episodes (``splits``: episode id -> split); splits without a record are left out."""
    return _per_group(grouped_runs(runs, dict.fromkeys(runs, splits), SPLITS), split_entry)


def split_entry(records: list[EpisodeRecord]) -> SplitEntry:
    """One method's columns of the per-split table over ``records``."""
    return SplitEntry.of(method_entry(records))


def group_entry(records: list[EpisodeRecord]) -> GroupEntry:
    """One method's columns of the floor groups' table over ``records``: the per-split ones and the successes."""
    return GroupEntry(split_entry(records), successes(records))


def _per_group(
    table: dict[str, RunRecords], entry: Callable[[list[EpisodeRecord]], _Entry]
) -> dict[str, dict[str, _Entry]]:
    """Each group's ``entry`` per method, over the method's records of the group."""
    return {group: {name: entry(list(records.values())) for name, records in by.items()} for group, by in table.items()}


def floor_groups(episodes: Sequence[Episode]) -> dict[str, str]:
    """Each episode's floor group (:data:`~drivenav.analysis.ablation_data.FLOOR_GROUPS`) by id; none at all where
    no episode carries ``info["cross_floor"]`` (one-floor benchmarks, v1's and v2's). In a set where some do, an
    episode without it lies in a scene of one storey."""
    if not any(isinstance(e.info.get(FLOOR_INFO), bool) for e in episodes):
        return {}
    return {e.episode_id: _floor_group(e.info.get(FLOOR_INFO)) for e in episodes}


def _floor_group(cross: object) -> str:
    if not isinstance(cross, bool):
        return ONE_FLOOR
    return CROSS_FLOOR if cross else SAME_FLOOR


def floor_entries(runs: RunRecords, groups: RunGroups, reference: str = PAIRED_REFERENCE) -> Floors | None:
    """Each method per floor group (``groups``: per method, its episodes' :func:`floor_groups`) and, within each
    group, every other method paired with ``reference`` (:func:`paired_outcomes`); None when no record is in a
    floor group."""
    table = grouped_runs(runs, groups, tuple(FLOOR_GROUPS))
    if not table:
        return None
    paired = {group: found for group, by in table.items() if (found := paired_outcomes(by, reference))}
    return Floors(reference, _per_group(table, group_entry), paired)


def build_report(
    dirs: dict[str, Path],
    runs: RunRecords,
    first: RunSpec,
    episodes: int,
    splits: Mapping[str, str] | None = None,
    floors: Mapping[str, str] | None = None,
    floor_reference: str = PAIRED_REFERENCE,
) -> AblationReport:
    """The ``ablations.json`` report for the finished runs in ``dirs`` (their records: ``runs``), without pictures;
    with ``splits`` (episode id -> vocabulary split), each method per split too; with ``floors`` (episode id ->
    floor group: :func:`floor_groups`), each method per floor group, paired with ``floor_reference``."""
    table_ii_methods = [name for name in TABLE_II_METHODS if name in dirs]
    scenes = world_json(first.env).get("scenes")
    return AblationReport(
        methods={name: method_entry(list(records.values())) for name, records in runs.items()},
        table_ii=compare_runs({name: runs[name] for name in table_ii_methods}),
        runtime=measure_runtime(runs, dirs),
        episodes=episodes,
        seed=first.seed,
        scenes=None if scenes is None else str(scenes),
        max_steps=first.max_steps,
        models=ReportModels(first.settings.models.reasoner, first.settings.models.detector),
        commit=git_commit(),
        splits=split_entries(runs, splits or {}),
        paired=paired_outcomes(runs),
        beyond=paired_entries(runs),
        table_ii_beyond=beyond_table_ii(runs, TABLE_II_METHODS),
        floors=floor_entries(runs, dict.fromkeys(runs, floors or {}), floor_reference),
    )


def run_ablations(
    episodes: list[Episode],
    specs: Sequence[RunSpec],
    out: Path,
    executor: Executor | None = None,
    pictures: int = 2,
    draw: PictureMaker | None = None,
    floor_reference: str = PAIRED_REFERENCE,
) -> AblationReport:
    """Run (or resume) every method, then write ``ablations.json``, ``.md`` and ``.csv`` into ``out``; with
    ``draw``, the pictures of ``pictures`` episodes for the Table II methods (else the first methods) too; episodes
    of vocabulary splits (``info["split"]``) give each method's results per split too, and episodes with
    ``info["cross_floor"]`` per floor group, paired with ``floor_reference``."""
    dirs = run_methods(episodes, specs, out, executor)
    runs = load_runs(dirs)
    splits, floors = episode_splits(episodes), floor_groups(episodes)
    report = build_report(dirs, runs, specs[0], len(episodes), splits, floors, floor_reference)
    if draw is not None:
        table_ii_first = sorted(dirs, key=lambda name: name not in TABLE_II_METHODS)
        order = [e.episode_id for e in episodes]
        drawn = draw({name: dirs[name] for name in table_ii_first}, runs, order, pictures, out)
        report = replace(report, pictures=drawn)
    (out / "ablations.json").write_text(json.dumps(report.to_json(), indent=2) + "\n", encoding="utf-8")
    (out / "ablations.md").write_text(format_markdown(report), encoding="utf-8")
    write_csv(report, out / "ablations.csv")
    return report
