"""One episode page per (episode, run): what happened, from the record and the trace.

The page shows the record's measures and, for an episode in a building, the floor it started on and the floors of
its goals; the top-down picture with the decisions (a building's: one map per storey), the other pictures and the
video where there are some; each direction decision with the candidate directions offered (the step of the
representative view each had then), the one chosen and the reasoner's answer; the detections, the verification
verdicts and the target decisions; the prompt enrichment; the per-step module timings as a small plot; links to
the trace and the record (copied into the site) and to the same episode in the other runs.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from drivenav.agent.base import CALL_MODELS, REASONER, CounterValue
from drivenav.agent.explorers import BUILT_IN_EXPLORERS
from drivenav.agent.trace import (
    DetectionEvent,
    DirectionSelected,
    Event,
    TargetAccepted,
    TargetRejected,
    TargetSetAside,
    VerificationEvent,
    event_fields,
    of_type,
)
from drivenav.analysis.counter_columns import explorer_entries
from drivenav.episode import Episode
from drivenav.eval.records import EpisodeRecord, missed_cause
from drivenav.eval.report import CALL_COLUMNS, shown
from drivenav.eval.trace import EpisodeTrace
from drivenav.report.config import ReportConfig
from drivenav.report.html import Cell, element, esc, link, page, table, void
from drivenav.report.pictures import SUFFIXES
from drivenav.report.timing_plot import timing_svg
from drivenav.viz.plugin_events import declared_events, foreign_events, spec_of
from drivenav.viz.saved_trace import SavedTrace
from drivenav.viz.thumbnails import capture_step

ROOT = "../../../"  # from runs/<run>/episodes/<page> to the site's folder


@dataclass(frozen=True)
class Sibling:
    """The same episode in another run: its name, its page (from the site's folder) and whether it succeeded."""

    run: str
    href: str
    success: str


@dataclass(frozen=True)
class EpisodeView:
    """Everything an episode page shows; paths are relative to the page."""

    run: str
    record: EpisodeRecord
    trace: EpisodeTrace | None
    saved: SavedTrace | None  # the trace placed in the world (None without the run's copy of the episode)
    pictures: tuple[str, ...]
    video: str | None
    trace_file: str | None
    record_file: str
    siblings: tuple[Sibling, ...]
    note: str = ""  # why a picture or the trace is missing
    episode: Episode | None = None  # None without the run's copy of its episodes


def _listed(value: object) -> str:
    """An episode info's value as text: a list's items joined by commas (a file's info is kept as given)."""
    return ", ".join(str(item) for item in value) if isinstance(value, list) else str(value)


def floor_facts(episode: Episode | None) -> list[tuple[str, str]]:
    """Where an episode in a building starts and where its goals are: the floors its info names (``start_floor``,
    ``goal_floors``, ``cross_floor``, as ``drivenav episodes generate`` writes them) with the heights of its start
    and of its goals' view points; nothing for an episode whose heights are all 0 and whose info names no floor."""
    if episode is None:
        return []
    info = episode.info
    heights = sorted({round(height, 1) for *_, height in episode.view_points_xyz()})
    named = {"start_floor", "goal_floors", "cross_floor"} & set(info)
    if not named and episode.start_height == 0 and not any(heights):
        return []
    start = f"at {episode.start_height:.1f} m"
    goals = "view points at " + (", ".join(f"{height:.1f} m" for height in heights) or "-")
    if "start_floor" in info:
        start = f"floor {_listed(info['start_floor'])} ({start})"
    if "goal_floors" in info:
        goals = f"floor {_listed(info['goal_floors'])} ({goals})"
    facts = [("start floor", start), ("goal floors", goals)]
    if "cross_floor" in info:
        facts.append(("floor change needed", "yes" if info["cross_floor"] is True else "no"))
    return facts


def _facts(record: EpisodeRecord, episode: Episode | None) -> str:
    cause = record.failure_cause
    if cause == "missed_target":
        cause += f" ({missed_cause(record)})"
    facts = [
        ("goal", record.object_category),
        ("scene", record.scene_id),
        *floor_facts(episode),
        ("success", shown(record.success, "{:.0f}")),
        ("SPL", shown(record.spl, "{:.3f}")),
        ("steps", str(record.steps)),
        ("path length", shown(record.path_length, "{:.2f} m")),
        ("geodesic distance", shown(record.geodesic_distance, "{:.2f} m")),
        ("distance to goal at the end", shown(record.distance_to_goal, "{:.2f} m")),
        ("revisits", f"{record.revisits} (retraced: {shown(record.retraced_revisits, '{:.0f}')})"),
        ("collisions", shown(record.collisions, "{:.0f}")),
        ("stop reason", record.stop_reason),
        ("failure cause", cause or "-"),
        ("model calls", str(record.vlm_calls)),
        *_calls(record),
        ("error", record.error or "-"),
    ]
    items = "".join(element("dt", esc(name)) + element("dd", esc(value)) for name, value in facts)
    return element("dl", items, {"class": "facts"})


def _calls(record: EpisodeRecord) -> list[tuple[str, str]]:
    """The reasoner's calls (with their kinds) and the image-text scorer's, each a fact of its own (n/a where the
    record cannot tell them apart)."""
    split = record.calls
    if split is None:
        return [(name, "n/a") for name in CALL_COLUMNS]
    kinds = sorted((kind, n) for kind, n in record.stats.vlm_calls_by_kind.items() if CALL_MODELS[kind] == REASONER)
    listed = ", ".join(f"{kind} {n}" for kind, n in kinds)
    return [
        (CALL_COLUMNS[0], f"{split.reasoner}" + (f" ({listed})" if listed else "")),
        (CALL_COLUMNS[1], f"{split.scorer}"),
    ]


def _picture(src: str, episode_id: str) -> str:
    """A picture scaled to the page's width, linked to itself at full size; the top-down picture (a building's is
    one map per storey side by side, wide) on a line of its own."""
    image = void("img", {"src": src, "alt": f"{Path(src).stem} of episode {episode_id}"})
    wide = "topdown" if src.endswith(SUFFIXES[0]) else None
    return element("figure", element("a", image, {"href": src}), {"class": wide})


def _media(view: EpisodeView) -> str:
    figures = "".join(_picture(src, view.record.episode_id) for src in view.pictures)
    if view.video is not None:
        figures += element("figure", element("video", "", {"src": view.video, "controls": "", "preload": "metadata"}))
    if not figures:
        figures = element("p", "No picture of this episode (see the report's --pictures and --max-pictures).")
    return element("h2", "Pictures", {"id": "pictures"}) + figures


def _degrees(radians: float) -> str:
    return f"{math.degrees(radians):.0f}°"


def _offered(view: EpisodeView, event: DirectionSelected) -> str:
    """The candidates of a decision, the chosen one in bold, each with the step its representative view was taken."""
    parts = []
    for label in event.candidates:
        step = None if view.saved is None else capture_step(view.saved, label, event.step)
        text = esc(f"D{label}" + ("" if step is None else f" (view of step {step})"))
        parts.append(element("strong", text) if label == event.label else text)
    return ", ".join(parts) or "-"


Rows = Iterable[Sequence[Cell | str]]


def _section(anchor: str, title: str, header: Sequence[str], rows: Rows, count: int, limit: int) -> str:
    """A heading and a table of at most ``limit`` rows (``count`` in all), or "None."."""
    heading = element("h2", esc(title), {"id": anchor})
    if not count:
        return heading + element("p", "None.")
    more = element("p", f"The first {limit} of {count}; the rest are in the trace.") if count > limit else ""
    return heading + table(header, rows) + more


def _decisions(view: EpisodeView, events: Sequence[Event], limit: int) -> str:
    decisions = of_type(events, DirectionSelected)
    rows: Rows = (
        [
            str(e.step),
            Cell(_offered(view, e)),
            f"D{e.label}",
            _degrees(e.bearing),
            e.reason + (" (fallback)" if e.fallback else ""),
        ]
        for e in decisions[:limit]
    )
    header = ["step", "directions offered (chosen in bold)", "chosen", "bearing", "reasoner's answer"]
    return _section("decisions", f"Direction decisions ({len(decisions)})", header, rows, len(decisions), limit)


def _point(point: tuple[float, float]) -> str:
    return f"({point[0]:.2f}, {point[1]:.2f})"


def _detections(events: Sequence[Event], limit: int) -> str:
    found = of_type(events, DetectionEvent)
    rows = ([str(e.step), e.phrase, f"{e.score:.3f}", _point(e.position)] for e in found[:limit])
    header = ["step", "phrase", "score", "position (episode frame, m)"]
    return _section("detections", f"Detections ({len(found)})", header, rows, len(found), limit)


def _target_row(event: Event) -> list[Cell | str]:
    """A verification verdict or a target decision as one row: step, candidate, what happened, where."""
    if isinstance(event, VerificationEvent):
        return [str(event.step), str(event.candidate), f"verification: {event.outcome}", "-"]
    if isinstance(event, TargetAccepted):
        return [str(event.step), str(event.candidate), "accepted as the target", _point(event.position)]
    if isinstance(event, TargetRejected):
        return [str(event.step), str(event.candidate), f"rejected ({event.reason})", _point(event.position)]
    assert isinstance(event, TargetSetAside)
    what = f"set aside until step {event.until} (unreachable)"
    return [str(event.step), str(event.candidate), what, _point(event.position)]


TARGET_EVENTS = (VerificationEvent, TargetAccepted, TargetRejected, TargetSetAside)


def _verification(events: Sequence[Event], limit: int) -> str:
    found = [e for e in events if isinstance(e, TARGET_EVENTS)]
    rows = (_target_row(e) for e in found[:limit])
    header = ["step", "candidate", "verdict or decision", "position (episode frame, m)"]
    return _section("verification", f"Verification and targets ({len(found)})", header, rows, len(found), limit)


def _enrichment(record: EpisodeRecord, events: Sequence[Event]) -> str:
    """Prompt enrichment: the rounds asked of the reasoner, the phrase that grounded the target, the detections of
    phrases other than the goal's."""
    stats = record.stats
    heading = element("h2", "Prompt enrichment", {"id": "enrichment"})
    if not stats.enrich_rounds:
        return heading + element("p", "No enrichment round.")
    goal = record.object_category.lower()
    enriched = sorted({e.phrase for e in of_type(events, DetectionEvent) if e.phrase.lower() != goal})
    text = f"{stats.enrich_rounds} round(s) proposing a detector phrase for \u201c{record.object_category}\u201d"
    text += f"; the phrase that grounded the target: \u201c{stats.phrase}\u201d" if stats.phrase else "; none grounded"
    if enriched:
        text += "; detections of the phrases " + ", ".join(f"\u201c{p}\u201d" for p in enriched)
    return heading + element("p", esc(text + "."))


def _builtin_explorer(record: EpisodeRecord) -> bool:
    """Whether the episode's explorer is one of drivenav's own (or the agent has none)."""
    return record.explorer is None or record.explorer.name in BUILT_IN_EXPLORERS


def _counter_value(value: CounterValue) -> str:
    if isinstance(value, dict):
        return ", ".join(f"{kind} {count}" for kind, count in value.items()) or "-"
    return f"{value:g}"


def _explorer_counters(record: EpisodeRecord) -> str:
    """A plug-in explorer's counters, titled as its entry declares them (by their names where it does not)."""
    explorer = record.explorer
    assert explorer is not None
    heading = element("h2", esc(f"Counters of the {explorer.name} explorer"), {"id": "counters"})
    if not explorer.counters:
        return heading + element("p", "None.")
    entries = {entry.name: entry for entry in explorer_entries([explorer.name])}
    entry = entries.get(explorer.name)
    facts = []
    for name, value in explorer.counters.items():
        spec = entry.counter(name) if entry is not None else None
        facts.append((spec.heading if spec is not None else name, _counter_value(value)))
    items = "".join(element("dt", esc(name)) + element("dd", esc(value)) for name, value in facts)
    return heading + element("dl", items, {"class": "facts"})


def _explorer_events(record: EpisodeRecord, events: Sequence[Event], limit: int) -> str:
    """The events of kinds drivenav has no section for (a plug-in's), each with its declared fields (all where it
    declares none)."""
    found = foreign_events(tuple(events))
    specs = declared_events(record)
    rows: Rows = (
        [str(e.step), spec_of(e, specs).legend, _event_fields(e, spec_of(e, specs).fields)] for e in found[:limit]
    )
    header = ["step", "event", "fields"]
    return _section("explorer-events", f"Explorer events ({len(found)})", header, rows, len(found), limit)


def _event_fields(event: Event, names: Sequence[str]) -> str:
    values = event_fields(event)
    shown_names = [name for name in names if name in values] if names else list(values)
    return "; ".join(f"{name}: {json.dumps(values[name])}" for name in shown_names) or "-"


def _explorer(view: EpisodeView, events: Sequence[Event], limit: int) -> str:
    """The explorer's sections: DRIVE-Nav's direction decisions for drivenav's own explorers (or where there are
    some); a plug-in's counters; the events of kinds drivenav has no section for, where there are some."""
    record = view.record
    html = ""
    if _builtin_explorer(record) or of_type(events, DirectionSelected):
        html += _decisions(view, events, limit)
    if not _builtin_explorer(record):
        html += _explorer_counters(record)
    if foreign_events(tuple(events)):
        html += _explorer_events(record, events, limit)
    return html


def _links(view: EpisodeView) -> str:
    files = [link(view.record_file, "the record (JSON)")]
    if view.trace_file is not None:
        files.append(link(view.trace_file, "the trace (JSON)"))
    items = "".join(element("li", item) for item in files)
    others = "".join(element("li", link(ROOT + s.href, s.run) + esc(f": success {s.success}")) for s in view.siblings)
    html = element("h2", "Files", {"id": "files"}) + element("ul", items)
    if others:
        html += element("h2", "This episode in the other runs", {"id": "others"}) + element("ul", others)
    return html


def _error(trace: EpisodeTrace | None) -> str:
    if trace is None or trace.error is None:
        return ""
    return element("h2", "Error", {"id": "error"}) + element("pre", esc(trace.error.traceback))


def episode_html(view: EpisodeView, config: ReportConfig) -> str:
    """The whole page."""
    record = view.record
    events = () if view.trace is None else view.trace.events
    title = f"Episode {record.episode_id} · {view.run}"
    back = element("p", link(f"{ROOT}episodes.html#method={view.run}", f"all episodes of {view.run}"))
    body = element("h1", esc(title)) + back + _facts(record, view.episode)
    if view.note:
        body += element("p", esc(view.note), {"class": "note"})
    body += _media(view) + _explorer(view, events, config.rows_per_table)
    body += _detections(events, config.rows_per_table) + _verification(events, config.rows_per_table)
    body += _enrichment(record, events)
    timings = timing_svg({} if view.trace is None else view.trace.step_ms, config)
    body += element("h2", "Module time per step", {"id": "timings"}) + timings
    body += _error(view.trace) + _links(view)
    return page(title, body, ROOT)
