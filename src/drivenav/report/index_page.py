"""The report's entry page, ``index.html``: one row per run (SR and SPL with their 95 % intervals, steps, revisits,
errors, reasoner and scorer calls), the settings in which the runs differ (from ``run.json``), and the paper's
tables when the runs form an ablation set."""

from __future__ import annotations

import json
from collections.abc import Sequence

from drivenav.analysis.ablation_data import Interval
from drivenav.analysis.stats import BOOTSTRAP_RESAMPLES
from drivenav.eval.report import CALL_COLUMNS, call_means, shown
from drivenav.report.html import Cell, element, esc, link, page, table
from drivenav.report.runs import Run, compared_configs, config_differences


def _rate(value: float | None, interval: Interval | None) -> Cell:
    text = shown(value, "{:.1f}", 100.0)
    if interval is not None:
        text += f" [{100 * interval[0]:.1f}, {100 * interval[1]:.1f}]"
    return Cell(esc(text), None if value is None else f"{value:.6f}")


def _world(run: Run) -> str:
    if run.info is None:
        return "-"
    scenes = run.info.world.get("scenes")
    return f"{run.info.world.get('name', '?')}" + (f" {scenes}" if scenes else "")


def _run_row(run: Run) -> list[Cell | str]:
    entry = run.entry
    name = link(f"episodes.html#method={run.name}", run.name)
    return [
        Cell(name, run.name),
        str(entry.episodes),
        _rate(entry.success_rate, entry.sr_ci95),
        _rate(entry.spl, entry.spl_ci95),
        shown(entry.avg_steps, "{:.1f}"),
        shown(entry.avg_revisits, "{:.3f}"),
        str(entry.errors),
        *(shown(value, "{:.2f}") for value in call_means(entry.calls)),
        _world(run),
        (run.info.git_commit or "-")[:10] if run.info else "-",
    ]


def _runs_table(runs: Sequence[Run]) -> str:
    header = ["run", "episodes", "SR %", "SPL %", "steps", "revisits", "errors", *CALL_COLUMNS, "world", "commit"]
    caption = (
        "SR and SPL in %, 95 % intervals in brackets (Wilson score for SR, percentile bootstrap of the mean with "
        f"{BOOTSTRAP_RESAMPLES} resamples for SPL); steps, revisits and model calls are means per episode (reasoner "
        "calls: questions to the reasoning model; scorer calls: frames the image-text scorer scored; n/a for records "
        "without calls by kind); errors are episodes an exception ended."
    )
    return element("p", esc(caption)) + table(header, (_run_row(run) for run in runs), {"class": "sortable"})


def _value(value: object) -> str:
    return "(unset)" if value is None else value if isinstance(value, str) else json.dumps(value)


def _differences(runs: Sequence[Run]) -> str:
    keys = config_differences(runs)
    title = element("h2", "Settings that differ between the runs", {"id": "differences"})
    if len(runs) < 2:
        return ""
    if not keys:
        return title + element("p", "None: every run has the same settings in its run.json.")
    configs = compared_configs(runs)
    rows = ([key, *(_value(config.get(key)) for config in configs)] for key in keys)
    return title + table(["setting", *(run.name for run in runs)], rows)


def index_html(runs: Sequence[Run], tables: str | None) -> str:
    """The whole index page."""
    total = sum(len(run.records) for run in runs)
    intro = element(
        "p",
        f"{len(runs)} run(s), {total} episode records. "
        + link("episodes.html", "Every episode")
        + " (sortable and filterable); "
        + link("pivot.html", "which episodes one run solved and another did not")
        + ".",
    )
    body = element("h1", "Run report") + intro + element("h2", "Runs", {"id": "runs"}) + _runs_table(runs)
    body += _differences(runs)
    if tables is not None:
        body += element("section", element("h2", "The paper's tables") + tables, {"id": "paper-tables"})
    return page("Run report", body, "", script=True)
