"""The paper's tables on the index page, when the report's runs form an ablation set (runs of the methods of
Tables I, II, V or VI on the same episodes).

The tables are ``ablations.md`` itself: read from the ``ablations.json`` that ``bench ablations`` wrote beside the
runs when it covers exactly these runs and its methods' numbers are theirs, else built from the runs as
``bench ablations`` builds it
(:func:`drivenav.analysis.ablations.build_report`), then written by
:func:`~drivenav.analysis.ablation_report.format_markdown` and shown as HTML. Its pictures section is left out: the
report's episode pages show every picture. An ``ablations.json`` that is not what ``bench ablations`` writes (no
JSON, another shape, values that do not print) is one :class:`~drivenav.errors.InputError` naming it.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace

from drivenav.analysis.ablation_data import AblationReport, Pictures
from drivenav.analysis.ablation_report import format_markdown
from drivenav.analysis.ablations import RUNS_DIR, build_report, floor_groups
from drivenav.analysis.paper_tables import TABLE_I, TABLE_II, TABLE_V, TABLE_VI
from drivenav.errors import InputError
from drivenav.eval.rundir import inside
from drivenav.eval.runner import RunSpec
from drivenav.jsonstream import DOCUMENT
from drivenav.report.markdown import to_html
from drivenav.report.runs import Run
from drivenav.worlds import recorded_world

ABLATIONS_JSON = "ablations.json"
PAPER_METHODS = frozenset(row.method for table in (TABLE_I, TABLE_II, TABLE_V, TABLE_VI) for row in table)
LEFT_OUT = frozenset({"Pictures"})


def is_ablation_set(runs: Sequence[Run]) -> bool:
    """Two or more runs, named by their methods, at least one a method of the paper's tables, on one episode set."""
    names = {run.name for run in runs}
    episode_sets = {frozenset(r.episode_id for r in run.records) for run in runs}
    return len(runs) > 1 and bool(names & PAPER_METHODS) and len(episode_sets) == 1


def paper_tables_html(runs: Sequence[Run]) -> str | None:
    """The tables as HTML, or None when the runs are no ablation set (or have no ``run.json`` to build them)."""
    if not is_ablation_set(runs):
        return None
    markdown = _stored(runs)
    if markdown is None:
        report = _built(runs)
        markdown = None if report is None else _markdown(report)
    return None if markdown is None else to_html(markdown, heading_shift=1, leave_out=LEFT_OUT)


def _markdown(report: AblationReport) -> str:
    return format_markdown(replace(report, pictures=Pictures()))


def _stored(runs: Sequence[Run]) -> str | None:
    """The tables of the ``ablations.json`` of a ``bench ablations`` folder holding exactly these runs, with their
    numbers (None otherwise: written before the runs finished, or for other runs)."""
    parents = {run.path.resolve().parent for run in runs}
    if len(parents) != 1 or next(iter(parents)).name != RUNS_DIR:
        return None
    folder = next(iter(parents)).parent
    path = folder / ABLATIONS_JSON
    if not path.is_file():
        return None
    expected = "an ablations.json written by 'drivenav bench ablations'"
    if inside(folder, ABLATIONS_JSON) is None:
        raise InputError(path, DOCUMENT, f"{expected}, inside its folder", "a link out of it")
    try:
        report = AblationReport.from_json(json.loads(path.read_text(encoding="utf-8")), path)
    except ValueError:
        raise InputError(path, DOCUMENT, expected, "no JSON") from None
    if report.methods != {run.name: run.entry for run in runs}:
        return None
    try:
        return _markdown(report)
    except (TypeError, ValueError, KeyError, AttributeError, IndexError) as error:
        raise InputError(path, DOCUMENT, expected, f"{type(error).__name__}: {error}") from None


def _built(runs: Sequence[Run]) -> AblationReport | None:
    first = runs[0].info
    if first is None:
        return None
    _, env = recorded_world(first.world, runs[0].path)
    dirs = {run.name: run.path for run in runs}
    records = {run.name: {r.episode_id: r for r in run.records} for run in runs}
    episodes = len(runs[0].records)
    floors = floor_groups(list(runs[0].episodes.values()))
    return build_report(dirs, records, RunSpec(env, first.config), episodes, runs[0].splits, floors)
