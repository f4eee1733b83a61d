"""The paper's ablation tables (II, V, VI, VII) on the embedded benchmark, and the fixed, versioned episode set.

``drivenav bench ablations`` runs every method once through :func:`drivenav.eval.runner.evaluate` into
``DIR/runs/<method>/`` (resumable) and writes ``DIR/ablations.json``, ``DIR/ablations.md`` and ``DIR/ablations.csv``.
The paper's numbers are hard-coded below for comparison only; nothing here is tuned to agree with them.
"""

from __future__ import annotations

import csv
import json
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from itertools import pairwise
from pathlib import Path
from typing import Any

from drivenav.envs.episode import Episode
from drivenav.envs.library import SceneLibrary
from drivenav.envs.rosmap import default_shared_maps_dir
from drivenav.errors import InputError
from drivenav.eval.compare import compare_runs, load_runs
from drivenav.eval.episodes import generate_episodes, load_episodes, save_episodes
from drivenav.eval.pictures import render_pictures
from drivenav.eval.provenance import git_commit
from drivenav.eval.records import ERROR, EpisodeRecord
from drivenav.eval.report import summarize
from drivenav.eval.rundir import trace_path
from drivenav.eval.runner import Executor, RunSpec, evaluate
from drivenav.eval.stats import BOOTSTRAP_RESAMPLES, bootstrap_mean_interval, wilson_interval
from drivenav.eval.timings import runtime_table, traced_steps
from drivenav.methods import METHODS
from drivenav.settings import agent_names
from drivenav.types import SimConfig

# ----------------------------------------------------------------------------------------------- the benchmark

SHARED_MAPS = "{shared_maps}"  # stands for drivenav.envs.rosmap.default_shared_maps_dir() in a scenes SPEC


@dataclass(frozen=True)
class BenchmarkDefinition:
    """A fixed episode set: a ``--scenes`` SPEC (may name ``{shared_maps}``), an episode count and a seed; once
    published, its episodes are frozen as a file shipped with drivenav (``frozen``, under ``drivenav/data``), so
    that no later change to the generator changes them."""

    scenes: str
    episodes: int
    seed: int
    frozen: str | None = None


BENCHMARK_V1 = BenchmarkDefinition(
    scenes=f"procedural:40,{SHARED_MAPS}", episodes=200, seed=2026, frozen="benchmarks/v1.json.gz"
)
"""v1: 200 episodes round-robin over 40 procedural houses and every shared real floor plan (a quarter by synonym),
as generated at its publication (sha256 3de8fb63...4955d8). Never change a published version; add a new one.
"""

BENCHMARKS: dict[str, BenchmarkDefinition] = {"v1": BENCHMARK_V1}


def resolve_scenes(spec: str) -> str:
    """``spec`` with ``{shared_maps}`` replaced by the shared floor plans folder (an error if there is none)."""
    if SHARED_MAPS not in spec:
        return spec
    maps = default_shared_maps_dir()
    if maps is None:
        raise InputError("DRIVENAV_SHARED", "--scenes", "a shared folder holding data/maps (the real floor plans)")
    return spec.replace(SHARED_MAPS, str(maps))


def generate_benchmark(definition: BenchmarkDefinition, episodes: int | None = None) -> list[Episode]:
    """The definition's episodes, the first ``episodes`` of them if given: its frozen file where it has one, else
    generated (generation is sequential, so a prefix is the same episodes)."""
    count = episodes or definition.episodes
    if definition.frozen is not None:
        with resources.as_file(resources.files("drivenav").joinpath(f"data/{definition.frozen}")) as path:
            return load_episodes(path)[:count]
    library = SceneLibrary(resolve_scenes(definition.scenes), definition.seed)
    return generate_episodes(library, count, definition.seed, SimConfig())


# ----------------------------------------------------------------------------------------------- the tables


@dataclass(frozen=True)
class PaperRow:
    """One method of a paper table: our agent name, the paper's label, the paper's two numbers."""

    method: str
    label: str
    paper: tuple[float, float]
    modules: tuple[bool, bool, bool, bool] = (True, True, True, True)  # Table VI check marks


# Paper values: DRIVE-Nav (seed paper 000_351b6498e965c216), HM3D-OVON val. Table VI (module ablation, SR / SPL %),
# Table V (directional-reasoning components, SR / SPL %), Table II (common successful episodes with start-to-goal
# distance > 10 m: average steps / average revisits).
TABLE_VI_MODULES = ("Frontier", "Directional", "Prompt Enrich.", "Verification")
TABLE_VI = (
    PaperRow("frontier", "Frontier", (42.1, 22.4), (True, False, False, False)),
    PaperRow("directional", "+ Directional", (46.3, 27.5), (True, True, False, False)),
    PaperRow("directional-enrich", "+ Prompt enrichment", (48.0, 28.9), (True, True, True, False)),
    PaperRow("directional-verify", "+ Verification", (48.8, 30.8), (True, True, False, True)),
    PaperRow("drive-nav", "DRIVE-Nav (full)", (50.2, 32.6)),
)
TABLE_V = (
    PaperRow("no-weighted-fmm", "w/o Weighted FMM", (44.5, 26.2)),
    PaperRow("no-240", "w/o 240° Inspection View", (45.5, 26.8)),
    PaperRow("directional", "Full Directional Reasoning Pipeline", (46.3, 27.5)),
)
TABLE_II = (
    PaperRow("nearest-frontier", "Nearest-edge-point greedy", (164.8, 0.200)),
    PaperRow("direction-360", "Direction inspection + 360° scan", (222.1, 0.200)),
    PaperRow("drive-nav", "DRIVE-Nav", (133.4, 0.132)),
)
TABLE_II_VLFM = (163.5, 0.364)  # the paper's VLFM row; VLFM is not implemented here
# Table VII (real-world workstation): SAM3 ~270 ms every step; FMM candidate generation ~15 ms per solve;
# direction selection ~8 s, few per episode; prompt enrichment ~3 s, sparse; verification ~3 s, up to 3 frames.
TABLE_VII_PAPER = (
    "SAM3 ~270 ms every step; FMM candidate generation ~15 ms per solve; direction selection ~8 s, a few per "
    "episode; prompt enrichment ~3 s, sparse; cross-frame verification ~3 s, up to 3 frames"
)

TABLE_II_METHODS = tuple(row.method for row in TABLE_II)
ALL_METHODS = tuple(method.name for method in METHODS)
FAILURE_CAUSES = ("false_positive_stop", "missed_target", "timeout", "no_frontier", "target_never_seen")
RUNS_DIR = "runs"
EPISODES_COPY = "episodes.json.gz"


def parse_methods(text: str) -> list[str]:
    """Agent names from ``--methods a,b,...`` (duplicates dropped, order kept)."""
    methods = list(dict.fromkeys(name.strip() for name in text.split(",") if name.strip()))
    known = agent_names()
    for name in methods or [text]:
        if name not in known:
            raise InputError("command line", "--methods", f"comma-separated agent names ({', '.join(known)})", name)
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


def method_entry(records: list[EpisodeRecord]) -> dict[str, Any]:
    """One method's ``ablations.json`` entry: SR / SPL with 95 % intervals, steps, revisits, calls, failures and
    errors (episodes an exception ended: counted apart, never as navigation failures)."""
    summary = summarize(records)
    measured = [r for r in records if r.success is not None]
    successes = sum(int(r.success or 0) for r in measured)
    return {
        "episodes": summary.episodes,
        "errors": summary.errors,
        "success_rate": summary.success_rate,
        "spl": summary.spl,
        "avg_steps": summary.avg_steps,
        "avg_revisits": summary.avg_revisits,
        "sr_ci95": _rounded(wilson_interval(successes, len(measured))) if measured else None,
        "spl_ci95": _rounded(bootstrap_mean_interval([float(r.spl or 0.0) for r in measured])) if measured else None,
        "vlm_calls": summary.avg_vlm_calls,
        "failure_causes": failure_counts(records),
    }


def _rounded(interval: tuple[float, float]) -> list[float]:
    return [round(interval[0], 6), round(interval[1], 6)]


def failure_counts(records: list[EpisodeRecord]) -> dict[str, int]:
    """Failed episodes by cause (every known cause listed, then any other cause found)."""
    counts = Counter(r.failure_cause or "unknown" for r in records if not r.success and r.failure_cause != ERROR)
    return {cause: counts.pop(cause, 0) for cause in FAILURE_CAUSES} | dict(sorted(counts.items()))


def model_call_latency(runs: dict[str, dict[str, EpisodeRecord]]) -> dict[str, dict[str, float]]:
    """Per model-call kind: mean latency per call, and calls per episode over the runs that make such calls."""
    calls: Counter[str] = Counter()
    latency: Counter[str] = Counter()
    episodes: Counter[str] = Counter()
    for records in runs.values():
        run_calls: Counter[str] = Counter()
        for record in records.values():
            run_calls.update(record.stats.vlm_calls_by_kind)
            latency.update(record.stats.vlm_latency_ms)
        calls.update(run_calls)
        episodes.update({kind: len(records) for kind, count in run_calls.items() if count})
    return {
        kind: {
            "calls": count,
            "calls_per_episode": round(count / episodes[kind], 3),
            "mean_latency_ms": round(latency[kind] / count, 3),
        }
        for kind, count in sorted(calls.items())
        if count
    }


RUNTIME_METHOD = "drive-nav"


def measure_runtime(runs: dict[str, dict[str, EpisodeRecord]], dirs: dict[str, Path]) -> dict[str, Any]:
    """Table VII from the runs themselves: per-step module timings saved in the traces of ``drive-nav`` (else
    the first method whose traces have them), model-call latency over every run. ``compute`` is None when no
    trace has timings."""
    sim = SimConfig()
    for method in sorted(dirs, key=lambda name: name != RUNTIME_METHOD):
        traces = (_read_trace(trace_path(dirs[method], episode_id)) for episode_id in runs[method])
        steps, decisions, episodes = traced_steps(traces)
        if steps:
            compute = runtime_table(steps, decisions, episodes, method, sim.width, sim.height)
            return {"compute": compute, "model_calls": model_call_latency(runs)}
    return {"compute": None, "model_calls": model_call_latency(runs)}


def _read_trace(path: Path) -> dict[str, Any]:
    try:
        trace: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}  # a missing or torn trace only leaves its steps out of the timings
    return trace


def build_report(
    dirs: dict[str, Path], runs: dict[str, dict[str, EpisodeRecord]], first: RunSpec, episodes: int
) -> dict[str, Any]:
    """The ``ablations.json`` payload for the finished runs in ``dirs`` (their records: ``runs``)."""
    table_ii_methods = [name for name in TABLE_II_METHODS if name in dirs]
    return {
        "methods": {name: method_entry(list(records.values())) for name, records in runs.items()},
        "table_ii": compare_runs({name: runs[name] for name in table_ii_methods}),
        "runtime": measure_runtime(runs, dirs),
        "episodes": episodes,
        "seed": first.seed,
        "scenes": first.to_config()["env"].get("scenes"),
        "max_steps": first.max_steps,
        "models": {"reasoner": first.settings.models.reasoner, "detector": first.settings.models.detector},
        "commit": git_commit(),
    }


def run_ablations(
    episodes: list[Episode],
    specs: Sequence[RunSpec],
    out: Path,
    executor: Executor | None = None,
    pictures: int = 2,
) -> dict[str, Any]:
    """Run (or resume) every method, then write ``ablations.json``, ``.md`` and ``.csv`` into ``out``, and the
    top-down pictures of ``pictures`` episodes for the Table II methods (else the first methods)."""
    dirs = run_methods(episodes, specs, out, executor)
    runs = load_runs(dirs)
    report = build_report(dirs, runs, specs[0], len(episodes))
    table_ii_first = sorted(dirs, key=lambda name: name not in TABLE_II_METHODS)
    order = [e.episode_id for e in episodes]
    report["pictures"] = render_pictures({name: dirs[name] for name in table_ii_first}, runs, order, pictures, out)
    (out / "ablations.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    (out / "ablations.md").write_text(format_markdown(report), encoding="utf-8")
    write_csv(report, out / "ablations.csv")
    return report


# ----------------------------------------------------------------------------------------------- csv


def flatten(entry: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested fields joined by dots; an interval ``[lo, hi]`` becomes ``name.lo`` and ``name.hi``."""
    flat: dict[str, Any] = {}
    for key, value in entry.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(flatten(value, f"{name}."))
        elif isinstance(value, list):
            flat.update({f"{name}.lo": value[0], f"{name}.hi": value[1]})
        else:
            flat[name] = value
    return flat


def write_csv(report: dict[str, Any], path: Path) -> None:
    """One row per method with its ``ablations.json`` fields flattened."""
    rows = [{"method": name, **flatten(entry)} for name, entry in report["methods"].items()]
    fields = list(dict.fromkeys(key for row in rows for key in row))
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields, restval=0)
        writer.writeheader()
        writer.writerows(rows)


# ----------------------------------------------------------------------------------------------- markdown


def format_markdown(report: dict[str, Any]) -> str:
    """``ablations.md``: the paper's tables with our numbers beside the paper's, failures, ordering differences."""
    commit = report["commit"] or "unknown"
    header = [
        "# Ablations on the embedded benchmark",
        "",
        f"{report['episodes']} episodes, seed {report['seed']}, scenes `{report['scenes']}`, at most "
        f"{report['max_steps']} steps, reasoner `{report['models']['reasoner']}`, detector "
        f"`{report['models']['detector']}`, commit {commit}. SR and SPL in %, with 95 % intervals in brackets "
        f"(Wilson score for SR, percentile bootstrap of the mean with {BOOTSTRAP_RESAMPLES} resamples for SPL). "
        "Paper values: HM3D-OVON (DRIVE-Nav, Tables II, V, VI, VII).",
    ]
    sections = [
        header,
        _table_vi(report["methods"]),
        _table_v(report["methods"]),
        _table_ii(report["table_ii"]),
        _table_vii(report["runtime"]),
        _failures(report["methods"]),
        _orderings(report),
        _pictures(report.get("pictures")),
    ]
    return "\n\n".join("\n".join(lines) for lines in sections) + "\n"


def _pictures(pictures: dict[str, Any] | None) -> list[str]:
    lines = ["## Pictures", ""]
    if not pictures or not pictures["episodes"]:
        return [*lines, "None drawn (`--pictures 0`, or no episode finished by every method)."]
    lines.append(
        "The same episodes for each method (`drivenav viz` top-down maps: path by segment, decisions, "
        "representative views, detections, goal); Table II episodes first."
    )
    for episode_id, by_method in pictures["episodes"].items():
        lines.extend(["", f"Episode `{episode_id}`:", ""])
        lines.append("| " + " | ".join(f"`{m}`" for m in by_method) + " |")
        lines.append("|" + "---|" * len(by_method))
        lines.append("| " + " | ".join(f"![{m}]({path})" for m, path in by_method.items()) + " |")
    if pictures["video"]:
        lines.extend(
            ["", f"Video (egocentric view beside the map, step by step): [{pictures['video']}]({pictures['video']})"]
        )
    return lines


def _pct(value: float | None, interval: list[float] | None) -> str:
    if value is None or interval is None:
        return "n/a"
    return f"{100 * value:.1f} [{100 * interval[0]:.1f}, {100 * interval[1]:.1f}]"


def _sr_spl(entry: dict[str, Any]) -> str:
    """SR and SPL with their intervals, then the episodes an exception ended."""
    sr, spl = _pct(entry["success_rate"], entry["sr_ci95"]), _pct(entry["spl"], entry["spl_ci95"])
    return f"{sr} | {spl} | {entry.get('errors', 0)}"


def _rows_present(rows: Sequence[PaperRow], methods: dict[str, Any]) -> list[PaperRow]:
    return [row for row in rows if row.method in methods]


def _not_run(lines: list[str], rows: Sequence[PaperRow]) -> list[str]:
    return lines if rows else [lines[0], "", "No method of this table was run."]


def _table_vi(methods: dict[str, Any]) -> list[str]:
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


def _table_v(methods: dict[str, Any]) -> list[str]:
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


def _table_ii(table: dict[str, Any]) -> list[str]:
    rows = _rows_present(TABLE_II, table["methods"])
    lines = [
        "## Table II: common successful episodes",
        "",
        f"Episodes every method below solved, start-to-goal geodesic distance > {table['min_distance']:g} m: "
        f"n = {table['common_episodes']}. Lower is better.",
        "",
        "| method | ours | avg steps | avg revisits | paper steps | paper revisits |",
        "|---|---|---|---|---|---|",
        f"| VLFM | (not implemented) | - | - | {TABLE_II_VLFM[0]:.1f} | {TABLE_II_VLFM[1]:.3f} |",
    ]
    for row in rows:
        common = table["methods"][row.method]["common"]
        ours = f"{common['avg_steps']:.1f} | {common['avg_revisits']:.3f}" if common else "- | -"
        lines.append(f"| {row.label} | `{row.method}` | {ours} | {row.paper[0]:.1f} | {row.paper[1]:.3f} |")
    return _not_run(lines, rows)


def _table_vii(runtime: dict[str, Any]) -> list[str]:
    lines = ["## Table VII: runtime", "", *_compute_rows(runtime["compute"])]
    for kind, calls in runtime["model_calls"].items():
        lines.append(
            f"| model call: {kind} | {calls['mean_latency_ms']:.1f} ms (mean) |"
            f" {calls['calls_per_episode']:.2f} per episode |"
        )
    lines.extend(["", f"Paper (real-world workstation): {TABLE_VII_PAPER}."])
    return lines


def _compute_rows(compute: dict[str, Any] | None) -> list[str]:
    header = ["", "| module | latency (median) | invocation |", "|---|---|---|"]
    if compute is None:
        return ["No per-step timings in these runs' traces; model calls only.", *header]
    rows = [
        f"Agent compute per step (models excluded), `{compute['agent']}`, every step of its {compute['episodes']} "
        f"episodes ({compute['steps']} steps, {compute['width']}x{compute['height']}): median "
        f"{compute['median_ms']:.1f} ms, p90 {compute['p90_ms']:.1f} ms. Model calls: mean latency per call over "
        "every run above, calls per episode over the runs of the methods that make them.",
        *header,
    ]
    for name, module in compute["modules"].items():
        latency = f"{module['median_ms']:.2f} ms" if "median_ms" in module else "-"
        count = f", {module['invocations']} in {compute['steps']} steps" if "invocations" in module else ""
        rows.append(f"| {name} | {latency} | {module['invocation']}{count} |")
    return rows


def _failures(methods: dict[str, Any]) -> list[str]:
    causes = list(dict.fromkeys(c for entry in methods.values() for c in entry["failure_causes"]))
    lines = [
        "## Failure causes",
        "",
        f"| method | episodes | failures | {' | '.join(causes)} |",
        "|---|---|---|" + "---|" * len(causes),
    ]
    for name, entry in methods.items():
        counts = entry["failure_causes"]
        cells = " | ".join(str(counts.get(c, 0)) for c in causes)
        lines.append(f"| `{name}` | {entry['episodes']} | {sum(counts.values())} | {cells} |")
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


def _orderings(report: dict[str, Any]) -> list[str]:
    methods = report["methods"]
    sr = {name: round(100 * entry["success_rate"], 1) for name, entry in methods.items()}
    spl = {name: round(100 * entry["spl"], 1) for name, entry in methods.items()}
    table_ii = report["table_ii"]
    common = {name: row["common"] for name, row in table_ii["methods"].items() if row["common"]}
    steps = {name: round(row["avg_steps"], 1) for name, row in common.items()}
    revisits = {name: round(row["avg_revisits"], 3) for name, row in common.items()}
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
    return lines
