"""How pictures draw the trace events of kinds drivenav has no drawing of: a plug-in explorer's own events, as its
entry declares them (:class:`~drivenav.agent.config.EventSpec`: marker, colour, label, where), and any other (an
undeclared kind, or a plug-in not installed where the trace is read) as a plain grey diamond at the agent's place,
labelled with its kind. A picture never fails on such an event."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from PIL import ImageDraw

from drivenav.agent.config import EventSpec
from drivenav.agent.explorers import explorer_entry
from drivenav.agent.trace import Event, Point, event_fields, event_name, is_builtin
from drivenav.errors import InputError
from drivenav.eval.records import EpisodeRecord

if TYPE_CHECKING:
    from drivenav.viz.saved_trace import SavedTrace

Draw = ImageDraw.ImageDraw
GENERIC_COLOR = (110, 110, 110)
RADIUS = 7.0
Specs = dict[str, EventSpec]


def declared_events(record: EpisodeRecord | None) -> Specs:
    """The event kinds the record's explorer declares, by kind (none without a record, an explorer, or where that
    explorer is not installed)."""
    if record is None or record.explorer is None:
        return {}
    try:
        entry = explorer_entry(record.explorer.name)
    except InputError:
        return {}
    return {spec.kind: spec for spec in entry.events}


def foreign_events(events: tuple[Event, ...]) -> list[Event]:
    """The events of kinds drivenav has no drawing of (a plug-in's, or kept opaque)."""
    return [event for event in events if not is_builtin(event)]


def spec_of(event: Event, specs: Specs) -> EventSpec:
    """How to draw ``event``: as declared, else the generic marker."""
    kind = event_name(event)
    return specs.get(kind) or EventSpec(kind, marker="diamond", color=GENERIC_COLOR)


def place(event: Event, spec: EventSpec, trace: SavedTrace) -> Point:
    """Where ``event`` is drawn (world frame): the point in its ``at`` field when it has one, else where the agent
    was at its step."""
    point = event_fields(event).get(spec.at) if spec.at else None
    if isinstance(point, (list, tuple)) and len(point) == 2 and all(_number(v) for v in point):
        return trace.to_world((float(point[0]), float(point[1])))
    return trace.xy(event.step)


def _number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def mark(draw: Draw, px: float, py: float, spec: EventSpec) -> None:
    """The declared marker of ``spec`` at picture coordinates."""
    r, color = RADIUS, spec.color
    shapes: dict[str, Callable[[], None]] = {
        "circle": lambda: draw.ellipse([px - r, py - r, px + r, py + r], outline=color, width=3),
        "square": lambda: draw.rectangle([px - r, py - r, px + r, py + r], outline=color, width=3),
        "cross": lambda: _cross(draw, px, py, color),
        "triangle": lambda: draw.polygon([(px, py - r), (px - r, py + r), (px + r, py + r)], outline=color, width=3),
        "diamond": lambda: draw.polygon(
            [(px, py - r), (px + r, py), (px, py + r), (px - r, py)], outline=color, width=3
        ),
    }
    shapes[spec.marker]()


def _cross(draw: Draw, px: float, py: float, color: tuple[int, int, int]) -> None:
    draw.line([(px - RADIUS, py - RADIUS), (px + RADIUS, py + RADIUS)], fill=color, width=3)
    draw.line([(px - RADIUS, py + RADIUS), (px + RADIUS, py - RADIUS)], fill=color, width=3)


def legend(events: list[Event], specs: Specs) -> list[tuple[str, Callable[[Draw, float, float], None]]]:
    """A legend entry per kind among ``events``, in order of first appearance."""
    kinds = {event_name(event): spec_of(event, specs) for event in events}
    return [(spec.legend, _marker(spec)) for spec in kinds.values()]


def _marker(spec: EventSpec) -> Callable[[Draw, float, float], None]:
    return lambda draw, px, py: mark(draw, px, py, spec)
