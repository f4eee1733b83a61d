"""``episodes.html``: one row per (episode, run), and ``pivot.html``: the episodes one run solved and another did
not.

The episodes table is complete without JavaScript. The script (``assets/report.js``) sorts it by any column and
filters it by success, failure cause, stop reason, category, scene, split, geodesic distance and run, and its
pivot keeps the episodes that one run solved and another did not; the filter state is kept in the page's address
(``episodes.html#success=0&method=frontier``), which is how the index and the pivot page link into it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from drivenav.agent.base import CallSplit
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.report import CALL_COLUMNS, shown
from drivenav.eval.rundir import file_name
from drivenav.report.html import Attributes, Cell, element, esc, link, page, row, table, void
from drivenav.report.runs import Run

COLUMNS = (
    "run",
    "episode",
    "scene",
    "category",
    "split",
    "success",
    "SPL",
    "steps",
    "geodesic m",
    "revisits",
    "stop reason",
    "failure cause",
    *CALL_COLUMNS,
)
FILTERS = (  # (field, label): the select filters, each over the values its column holds
    ("method", "run"),
    ("success", "success"),
    ("cause", "failure cause"),
    ("stop", "stop reason"),
    ("category", "category"),
    ("scene", "scene"),
    ("split", "split"),
)


def episode_page_path(run: Run, episode_id: str) -> str:
    """An episode page's path inside the site."""
    return f"runs/{run.slug}/episodes/{run.stem(episode_id)}.html"


def success_text(success: int | None) -> str:
    return "n/a" if success is None else "yes" if success else "no"


@dataclass(frozen=True)
class EpisodeRow:
    """One (episode, run) row: the run and the record, with the episode's split."""

    run: Run
    record: EpisodeRecord

    @property
    def split(self) -> str:
        return self.run.splits.get(self.record.episode_id, "")

    def data(self) -> Attributes:
        """The row's values the script filters by (``data-*``)."""
        record = self.record
        return {
            "data-method": self.run.name,
            "data-episode": record.episode_id,
            "data-success": "" if record.success is None else str(record.success),
            "data-cause": record.failure_cause,
            "data-stop": record.stop_reason,
            "data-category": record.canonical_category,
            "data-scene": record.scene_id,
            "data-split": self.split,
            "data-geo": "" if record.geodesic_distance is None else f"{record.geodesic_distance:.4f}",
        }

    def cells(self) -> list[Cell | str]:
        record = self.record
        category = record.object_category
        if record.canonical_category and record.canonical_category != category:
            category += f" ({record.canonical_category})"
        return [
            self.run.name,
            Cell(link(episode_page_path(self.run, record.episode_id), record.episode_id), _id_order(record.episode_id)),
            record.scene_id,
            category,
            self.split,
            success_text(record.success),
            _number(record.spl, "{:.3f}"),
            _number(record.steps, "{:.0f}"),
            _number(record.geodesic_distance, "{:.2f}"),
            _number(record.revisits, "{:.0f}"),
            record.stop_reason,
            record.failure_cause,
            *(_number(count, "{:.0f}") for count in _calls(record.calls)),
        ]


def _calls(split: CallSplit | None) -> tuple[int | None, int | None]:
    """The reasoner's and the scorer's calls (None where the record cannot tell them apart)."""
    return (None, None) if split is None else (split.reasoner, split.scorer)


def _number(value: float | None, template: str) -> Cell:
    return Cell(esc(shown(value, template)), "" if value is None else repr(value))


def _id_order(episode_id: str) -> str:
    """The sort key of an id in the table: a numeric id (ASCII digits) zero-padded, never converted to a number."""
    return f"{episode_id:0>12}" if episode_id.isascii() and episode_id.isdigit() else episode_id


def episode_rows(runs: Sequence[Run]) -> list[EpisodeRow]:
    return [EpisodeRow(run, record) for run in runs for record in run.records]


SUCCESS_LABELS = {"1": "succeeded", "0": "failed"}


def _select(field: str, label: str, values: Sequence[str]) -> str:
    """A select over the non-empty ``values`` (its first option, "any", filters nothing)."""
    options = element("option", "any", {"value": ""}) + "".join(
        element("option", esc(SUCCESS_LABELS.get(value, value) if field == "success" else value), {"value": value})
        for value in values
        if value
    )
    return element("label", esc(label) + " " + element("select", options, {"name": field, "id": f"filter-{field}"}))


def _filters(rows: Sequence[EpisodeRow], runs: Sequence[Run]) -> str:
    values = {field: sorted({str(r.data()[f"data-{field}"]) for r in rows}) for field, _ in FILTERS}
    selects = "".join(_select(field, label, values[field]) for field, label in FILTERS)
    distance = "".join(
        element(
            "label",
            f"geodesic {bound} (m) " + void("input", {"type": "number", "step": "0.5", "name": f"geo-{bound}"}),
        )
        for bound in ("min", "max")
    )
    names = [run.name for run in runs]
    pivot = element(
        "fieldset",
        element("legend", "pivot: the episodes one run solved and another did not")
        + _select("solved", "solved by", names)
        + _select("unsolved", "not solved by", names),
    )
    reset = element("button", "clear filters", {"type": "reset"})
    status = element("output", "", {"id": "row-count", "aria-live": "polite"})
    return element(
        "form",
        element("fieldset", element("legend", "filters") + selects + distance) + pivot + reset + status,
        {"id": "filters", "hidden": "", "aria-controls": "episodes"},
    )


def episodes_html(runs: Sequence[Run]) -> str:
    """The whole episodes page."""
    rows = episode_rows(runs)
    body_rows = "".join(row(r.cells(), r.data()) for r in rows)
    head = "".join(element("th", esc(name), {"scope": "col"}) for name in COLUMNS)
    grid = element(
        "table",
        f"<thead><tr>{head}</tr></thead><tbody>{body_rows}</tbody>",
        {"id": "episodes", "class": "sortable filterable"},
    )
    intro = element(
        "p",
        f"{len(rows)} rows, one per episode and run. Click a column header to sort; an episode id opens its page.",
    )
    body = element("h1", "Episodes") + intro + _filters(rows, runs) + grid
    return page("Episodes", body, "", script=True)


def _solved(runs: Sequence[Run]) -> dict[str, dict[str, int | None]]:
    return {run.name: {r.episode_id: r.success for r in run.records} for run in runs}


def pivot_pairs(runs: Sequence[Run]) -> dict[tuple[str, str], list[str]]:
    """For each ordered pair of runs (a, b): the episode ids a solved and b ran and did not solve."""
    solved = _solved(runs)
    pairs = {}
    for a in runs:
        for b in runs:
            if a is b:
                continue
            ids = [i for i, s in solved[a.name].items() if s and i in solved[b.name] and solved[b.name][i] == 0]
            pairs[(a.name, b.name)] = ids
    return pairs


def _anchor(a: str, b: str) -> str:
    """The id of a pair's list: no two pairs share one (``~~`` is in no :func:`file_name`)."""
    return f"pair-{file_name(a)}~~{file_name(b)}"


def pivot_html(runs: Sequence[Run]) -> str:
    """The pivot page: a matrix of counts (row solved, column did not) and each pair's episodes, linked to their
    pages in both runs."""
    pairs = pivot_pairs(runs)
    by_name = {run.name: run for run in runs}

    def count(a: Run, b: Run) -> Cell | str:
        if a is b:
            return "-"
        ids = pairs[(a.name, b.name)]
        return Cell(link(f"#{_anchor(a.name, b.name)}", str(len(ids))), str(len(ids))) if ids else "0"

    matrix = table(
        ["solved by \\ not solved by", *(run.name for run in runs)],
        ([Cell(esc(a.name)), *(count(a, b) for b in runs)] for a in runs),
        {"id": "pivot-matrix"},
    )
    lists = []
    for (a, b), ids in pairs.items():
        if not ids:
            continue
        items = "".join(
            element(
                "li",
                f"{esc(i)}: "
                + link(episode_page_path(by_name[a], i), a)
                + " · "
                + link(episode_page_path(by_name[b], i), b),
            )
            for i in ids
        )
        filtered = link(f"episodes.html#solved={a}&unsolved={b}", "in the episodes table")
        title = element("h3", f"solved by {esc(a)}, not by {esc(b)}: {len(ids)} ({filtered})")
        lists.append(element("section", title + element("ul", items), {"id": _anchor(a, b)}))
    intro = element(
        "p",
        "Each cell counts the episodes that the row's run solved and the column's run ran and did not solve; "
        "click it for the list.",
    )
    body = element("h1", "Pivot") + intro + matrix + "".join(lists)
    return page("Pivot", body, "")
