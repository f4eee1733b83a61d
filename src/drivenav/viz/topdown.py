"""Top-down episode pictures: walls, rooms, objects, goals, the explored area, and the agent's trace on top.

:class:`Canvas` maps world metres to pixels of a cropped, scaled structure grid under a one-line header. The
trace overlay is drawn event by event (:func:`draw_event`, :func:`draw_move`), so a video can add it step by step
to a map drawn once, and a picture draws it all at once (:func:`draw_episode`).

A building gets one map per storey (:mod:`drivenav.viz.floors`), all on one canvas: each shows its storey's plan,
the stairs rising from it, its stairwell and railings, the goals and view points on it, and what happened on it
(the part of the path walked there, the trace's events at its poses, where the path leaves and enters it).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw, ImageFont

from drivenav.agent.trace import (
    DetectionEvent,
    DirectionSelected,
    Event,
    EventT,
    InspectionStarted,
    Point,
    TargetAccepted,
    TargetRejected,
)
from drivenav.envs.embedded.building import Building, Flight, Rect, storeys_of
from drivenav.envs.embedded.palette import category_color
from drivenav.envs.embedded.scene import Material, Scene
from drivenav.episode import Episode
from drivenav.eval.records import EpisodeRecord
from drivenav.eval.report import shown
from drivenav.types import Pose
from drivenav.viz import plugin_events
from drivenav.viz.directions import label_color
from drivenav.viz.floors import Floor, floor_changes, floors_of, move_floors, pose_floors
from drivenav.viz.saved_trace import SavedTrace

RGB = tuple[int, int, int]
Draw = ImageDraw.ImageDraw
Marker = Callable[[Draw, float, float], None]  # draws a symbol at picture coordinates

MAX_SIDE = 1000  # pixels of the longer side of the map area
FLOOR_SIDE = 700  # the same for each storey's map of a building (they lie side by side)
FLOOR_GAP = 12  # pixels between two storeys' maps
MARGIN_CELLS = 10
HEADER = 28
LEGEND_WIDTH = 250
FONT = ImageFont.load_default(size=13)
SMALL_FONT = ImageFont.load_default(size=11)
STRUCTURE_COLORS = {
    Material.FREE: (236, 236, 230),
    Material.WALL: (45, 45, 50),
    Material.DOOR_FRAME: (140, 95, 55),
    Material.UNKNOWN: (165, 165, 170),
}
EXPLORED_TINT = (255, 214, 110)
EXPLORED_ALPHA = 0.55  # weight of the tint blended into explored free cells
START_COLOR = (30, 90, 220)
SUCCESS_COLOR = (20, 160, 40)
FAILURE_COLOR = (210, 30, 30)
GOAL_OUTLINE = (220, 20, 20)
VIEW_POINT_COLOR = (20, 120, 50)
INSPECTION_COLOR = (150, 60, 200)
DETECTION_COLOR = (235, 150, 0)
SEGMENT_RAMP = ((40, 70, 200), (150, 50, 170), (215, 50, 70), (240, 140, 0))
STAIRS_TINT = (110, 160, 215)
STAIRS_ALPHA = 0.5  # weight of the tint blended into the cells of stairs rising from a floor
TREAD_COLOR = (50, 80, 140)
HOLE_COLOR = (35, 45, 80)  # a stairwell: the floor is open onto the storey below
RAILING_COLOR = (0, 140, 150)
FLOOR_CHANGE_COLOR = (20, 20, 20)
ARROW_LENGTH = 1.2  # metres, along a selected direction's bearing


class Canvas:
    """World-to-pixel mapping of a cropped structure grid scaled so its longer side is ``max_side`` pixels (a
    building's: the crop of every storey's known cells, so that its storeys' maps are alike)."""

    def __init__(self, world: Scene | Building, max_side: int = MAX_SIDE, header: int = HEADER) -> None:
        storeys = storeys_of(world)
        grid = storeys[0].plan.grid
        known = np.argwhere(np.any([s.plan.structure != Material.UNKNOWN for s in storeys], axis=0))
        if len(known) == 0:
            known = np.array([[0, 0], [grid.shape[0] - 1, grid.shape[1] - 1]])
        lo = np.maximum(known.min(axis=0) - MARGIN_CELLS, 0)
        hi = np.minimum(known.max(axis=0) + MARGIN_CELLS + 1, grid.shape)
        self.rows = (int(lo[0]), int(hi[0]))
        self.cols = (int(lo[1]), int(hi[1]))
        self.scale = max_side / max(self.rows[1] - self.rows[0], self.cols[1] - self.cols[0])
        self.header = header
        self.res = grid.resolution
        self.x0 = grid.origin[0] + self.cols[0] * self.res
        self.y1 = grid.origin[1] + self.rows[1] * self.res

    @property
    def size(self) -> tuple[int, int]:
        """Width and height of the picture (header included)."""
        rows, cols = self.rows[1] - self.rows[0], self.cols[1] - self.cols[0]
        return round(cols * self.scale), round(rows * self.scale) + self.header

    def to_pixel(self, x: float, y: float) -> tuple[float, float]:
        return (x - self.x0) / self.res * self.scale, (self.y1 - y) / self.res * self.scale + self.header

    def length(self, metres: float) -> float:
        return metres / self.res * self.scale

    def window(self, grid: NDArray[Any]) -> NDArray[Any]:
        return grid[self.rows[0] : self.rows[1], self.cols[0] : self.cols[1]]

    def base_image(self, floor: Floor, explored: NDArray[np.bool_] | None = None) -> Image.Image:
        """A floor's structure (rooms tinted, explored free cells tinted, the stairs rising from it tinted, its
        stairwell dark) under a white header."""
        window = self.window(floor.plan.structure)
        rgb = np.zeros((*window.shape, 3), dtype=np.float64)
        for material, color in STRUCTURE_COLORS.items():
            rgb[window == material] = color
        free = window == Material.FREE
        rooms = self.window(floor.plan.room_index)
        rgb[free & (rooms > 0) & (rooms % 2 == 0)] = (226, 232, 238)
        if explored is not None:
            _tint(rgb, free & self.window(explored), EXPLORED_TINT, EXPLORED_ALPHA)
        if floor.stair_cells is not None:
            _tint(rgb, free & self.window(floor.stair_cells), STAIRS_TINT, STAIRS_ALPHA)
        if floor.hole is not None:
            rgb[self.window(floor.hole)] = HOLE_COLOR
        width, height = self.size
        grid = Image.fromarray(rgb[::-1].astype(np.uint8)).resize(
            (width, height - self.header), Image.Resampling.NEAREST
        )
        image = Image.new("RGB", (width, height), (255, 255, 255))
        image.paste(grid, (0, self.header))
        return image


def _tint(rgb: NDArray[np.float64], cells: NDArray[np.bool_], tint: RGB, alpha: float) -> None:
    """Blend ``tint`` with weight ``alpha`` into the ``cells`` of an image array, in place."""
    rgb[cells] = (1.0 - alpha) * rgb[cells] + alpha * np.array(tint)


def blended(color: RGB, tint: RGB, alpha: float) -> RGB:
    """``color`` with ``tint`` blended in with weight ``alpha`` (what :func:`_tint` makes of it)."""
    r, g, b = ((1.0 - alpha) * np.array(color) + alpha * np.array(tint)).astype(int)
    return int(r), int(g), int(b)


def darker(color: RGB, factor: float = 0.6) -> RGB:
    r, g, b = color
    return int(r * factor), int(g * factor), int(b * factor)


def lighter(color: RGB, white: float = 0.35) -> RGB:
    r, g, b = (round(c + white * (255 - c)) for c in color)
    return r, g, b


def segment_color(index: int, count: int) -> RGB:
    """Colour of trajectory segment ``index`` of ``count``: a ramp from blue (first) to orange (last)."""
    t = index / max(count - 1, 1) * (len(SEGMENT_RAMP) - 1)
    k = min(int(t), len(SEGMENT_RAMP) - 2)
    a, b = np.array(SEGMENT_RAMP[k]), np.array(SEGMENT_RAMP[k + 1])
    r, g, bl = (a + (t - k) * (b - a)).round().astype(int)
    return int(r), int(g), int(bl)


# ---------------------------------------------------------------------------------------------- markers (pixels)


def _disc(
    draw: Draw, px: float, py: float, radius: float, fill: RGB | None, outline: RGB | None, width: int = 1
) -> None:
    draw.ellipse([px - radius, py - radius, px + radius, py + radius], fill=fill, outline=outline, width=width)


def _cross(draw: Draw, px: float, py: float, radius: float, color: RGB, width: int) -> None:
    draw.line([(px - radius, py - radius), (px + radius, py + radius)], fill=color, width=width)
    draw.line([(px - radius, py + radius), (px + radius, py - radius)], fill=color, width=width)


def _arrow(draw: Draw, start: tuple[float, float], end: tuple[float, float], color: RGB) -> None:
    draw.line([start, end], fill=color, width=3)
    angle = math.atan2(end[1] - start[1], end[0] - start[0])
    head = [(end[0] - 9 * math.cos(angle + s * 0.45), end[1] - 9 * math.sin(angle + s * 0.45)) for s in (-1.0, 1.0)]
    draw.polygon([end, *head], fill=color)


def mark_pose(draw: Draw, px: float, py: float, radius: float, heading: float, color: RGB) -> None:
    """A ring with a heading tick; ``heading`` is in picture coordinates (radians, y down)."""
    _disc(draw, px, py, radius, None, color, 3)
    tip = (px + 2.2 * radius * math.cos(heading), py + 2.2 * radius * math.sin(heading))
    draw.line([(px, py), tip], fill=color, width=3)


def mark_decision(
    draw: Draw, robot: tuple[float, float], tip: tuple[float, float], goal: tuple[float, float], color: RGB
) -> None:
    """A selected direction: a square at the robot, an arrow along the bearing, a dot at the goal."""
    draw.rectangle([robot[0] - 4, robot[1] - 4, robot[0] + 4, robot[1] + 4], fill=color, outline=(0, 0, 0))
    _arrow(draw, robot, tip, color)
    _disc(draw, *goal, 6, color, (0, 0, 0), 2)


def mark_inspection(draw: Draw, px: float, py: float) -> None:
    _disc(draw, px, py, 11, None, INSPECTION_COLOR, 3)


def mark_detection(draw: Draw, px: float, py: float) -> None:
    _cross(draw, px, py, 4, DETECTION_COLOR, 2)


def mark_accepted(draw: Draw, px: float, py: float) -> None:
    _disc(draw, px, py, 9, None, SUCCESS_COLOR, 4)


def mark_rejected(draw: Draw, px: float, py: float) -> None:
    _cross(draw, px, py, 8, FAILURE_COLOR, 4)


def mark_floor_change(draw: Draw, px: float, py: float, up: bool, leaving: bool) -> None:
    """Where the path changes floors: a triangle pointing up or down the stairs, filled where it leaves the floor
    drawn, hollow where it enters it."""
    tip = -9.0 if up else 9.0
    corners = [(px, py + tip), (px - 8, py - tip * 0.7), (px + 8, py - tip * 0.7)]
    draw.polygon(corners, fill=FLOOR_CHANGE_COLOR if leaving else (255, 255, 255), outline=FLOOR_CHANGE_COLOR, width=2)


# ---------------------------------------------------------------------------------------------- scene and trace


def draw_floor(
    floor: Floor, episode: Episode, canvas: Canvas, explored: NDArray[np.bool_] | None = None
) -> Image.Image:
    """A floor's structure, room names, objects (goals outlined in red), stairs, railings and the goals' view points
    on it."""
    scene = floor.plan
    image = canvas.base_image(floor, explored)
    draw = ImageDraw.Draw(image)
    for room in scene.rooms:
        xs, ys = zip(*room.polygon, strict=True)
        draw.text(
            canvas.to_pixel(sum(xs) / len(xs), sum(ys) / len(ys)),
            room.name,
            fill=(120, 120, 140),
            anchor="mm",
            font=SMALL_FONT,
        )
    goal_ids = {g.object_id for g in episode.goals}
    for obj in scene.objects:
        corners = [canvas.to_pixel(x, y) for x, y in obj.footprint()]
        color = lighter(category_color(obj.category))
        draw.polygon(corners, fill=color, outline=darker(color))
        if obj.instance_id in goal_ids:
            draw.line([*corners, corners[0]], fill=GOAL_OUTLINE, width=3)
    _draw_stairs(draw, canvas, floor)
    for x, y, z in episode.view_points_xyz():
        if floor.holds(z):
            _disc(draw, *canvas.to_pixel(x, y), 1.5, VIEW_POINT_COLOR, None)
    return image


def _pixel_rect(canvas: Canvas, rect: Rect) -> list[float]:
    """A world rectangle as picture corners ``[left, top, right, bottom]``."""
    x0, y0, x1, y1 = rect
    left, bottom = canvas.to_pixel(x0, y0)
    right, top = canvas.to_pixel(x1, y1)
    return [left, top, right, bottom]


def _draw_flight(draw: Draw, canvas: Canvas, flight: Flight) -> None:
    """A flight's tread edges across it and an arrow up its middle."""
    for k in range(flight.risers):
        x0, y0, x1, y1 = flight.rect(k * flight.going, k * flight.going)
        draw.line([canvas.to_pixel(x0, y0), canvas.to_pixel(x1, y1)], fill=TREAD_COLOR, width=1)
    (fx, fy), (ux, uy), run = flight.foot, flight.axis, flight.run
    tail = canvas.to_pixel(fx + 0.15 * run * ux, fy + 0.15 * run * uy)
    _arrow(draw, tail, canvas.to_pixel(fx + run * ux, fy + run * uy), TREAD_COLOR)


def _draw_stairs(draw: Draw, canvas: Canvas, floor: Floor) -> None:
    """The flights and landings of the stairs rising from a floor, and the railings along its stairwell."""
    for stair in floor.stairs:
        for landing in stair.landings:
            draw.rectangle(_pixel_rect(canvas, landing.rect), outline=TREAD_COLOR, width=1)
        for flight in stair.flights:
            _draw_flight(draw, canvas, flight)
    for railing in floor.railings:
        draw.rectangle(_pixel_rect(canvas, railing.rect), fill=RAILING_COLOR, outline=RAILING_COLOR, width=2)


def draw_pose(draw: Draw, canvas: Canvas, xy: Point, yaw: float, color: RGB) -> None:
    px, py = canvas.to_pixel(*xy)
    mark_pose(draw, px, py, max(5.0, canvas.length(0.25)), -yaw, color)


def draw_view_cone(draw: Draw, canvas: Canvas, pose: Pose, hfov: float, color: RGB, reach: float = 2.0) -> None:
    """The camera's horizontal field of view from ``pose`` as a wedge ``reach`` metres deep."""
    corners = [
        canvas.to_pixel(pose.x + reach * math.cos(edge), pose.y + reach * math.sin(edge))
        for edge in (pose.yaw - hfov / 2, pose.yaw + hfov / 2)
    ]
    draw.polygon([canvas.to_pixel(pose.x, pose.y), *corners], outline=color, width=2)


def draw_move(draw: Draw, canvas: Canvas, trace: SavedTrace, step: int, color: RGB) -> None:
    """The move from pose ``step`` to pose ``step + 1``."""
    draw.line([canvas.to_pixel(*trace.xy(step)), canvas.to_pixel(*trace.xy(step + 1))], fill=color, width=3)


def draw_trajectory(draw: Draw, canvas: Canvas, trace: SavedTrace, moves: NDArray[np.bool_] | None = None) -> None:
    """The path, one polyline per segment (per stretch of it, when only the moves set in ``moves`` are drawn: those
    on one floor), coloured along :func:`segment_color`."""
    segments = trace.segments()
    for index, (first, last) in enumerate(segments):
        for start, end in [(first, last)] if moves is None else _stretches(moves, first, last):
            points = [canvas.to_pixel(*trace.xy(step)) for step in range(start, end + 1)]
            draw.line(points, fill=segment_color(index, len(segments)), width=3, joint="curve")


def _stretches(moves: NDArray[np.bool_], first: int, last: int) -> list[tuple[int, int]]:
    """The first and last pose of each run of consecutive moves set in ``moves`` between poses ``first`` and
    ``last``."""
    steps = np.flatnonzero(moves[first:last]) + first
    if len(steps) == 0:
        return []
    breaks = np.flatnonzero(np.diff(steps) > 1)
    starts, ends = [steps[0], *steps[breaks + 1]], [*steps[breaks], steps[-1]]
    return [(int(a), int(b) + 1) for a, b in zip(starts, ends, strict=True)]


def draw_floor_change(
    draws: Sequence[Draw], canvas: Canvas, trace: SavedTrace, floors: NDArray[np.int64], move: int
) -> None:
    """The markers of a move between two floors (``floors``: per pose, its floor; ``draws``: per floor, its map):
    where the path leaves the one floor and where it enters the other."""
    before, after = int(floors[move]), int(floors[move + 1])
    mark_floor_change(draws[before], *canvas.to_pixel(*trace.xy(move)), after > before, leaving=True)
    mark_floor_change(draws[after], *canvas.to_pixel(*trace.xy(move + 1)), after > before, leaving=False)


def _draw_decision(draw: Draw, canvas: Canvas, trace: SavedTrace, event: DirectionSelected) -> None:
    x, y = trace.xy(event.step)
    bearing = trace.world_yaw(event.bearing)
    tip = canvas.to_pixel(x + ARROW_LENGTH * math.cos(bearing), y + ARROW_LENGTH * math.sin(bearing))
    goal = canvas.to_pixel(*trace.to_world(event.goal))
    color = label_color(event.label)
    mark_decision(draw, canvas.to_pixel(x, y), tip, goal, color)
    draw.text(
        (goal[0] + 8, goal[1] - 8),
        f"D{event.label}",
        fill=darker(color, 0.7),
        font=FONT,
        stroke_width=2,
        stroke_fill=(255, 255, 255),
    )


class Placed(Protocol):
    """An event with a world point in the episode frame (a detection, an accepted or rejected target)."""

    @property
    def position(self) -> Point: ...


EventDrawer = Callable[[Draw, Canvas, SavedTrace, Event], None]


def _at_step(mark: Marker) -> Callable[[Draw, Canvas, SavedTrace, Event], None]:
    """Draw ``mark`` where the robot was at the event's step."""
    return lambda draw, canvas, trace, event: mark(draw, *canvas.to_pixel(*trace.xy(event.step)))


def _at_position(mark: Marker) -> Callable[[Draw, Canvas, SavedTrace, Placed], None]:
    """Draw ``mark`` at the event's own point."""
    return lambda draw, canvas, trace, event: mark(draw, *canvas.to_pixel(*trace.to_world(event.position)))


def _drawer(
    kind: type[EventT], draw_event: Callable[[Draw, Canvas, SavedTrace, EventT], None]
) -> tuple[type[Event], EventDrawer]:
    """``kind`` and a drawer of any event that draws those of type ``kind`` with ``draw_event``."""

    def drawer(draw: Draw, canvas: Canvas, trace: SavedTrace, event: Event) -> None:
        if isinstance(event, kind):
            draw_event(draw, canvas, trace, event)

    return kind, drawer


EVENT_DRAWERS: dict[type[Event], EventDrawer] = dict(
    [
        _drawer(InspectionStarted, _at_step(mark_inspection)),
        _drawer(DetectionEvent, _at_position(mark_detection)),
        _drawer(DirectionSelected, _draw_decision),
        _drawer(TargetRejected, _at_position(mark_rejected)),
        _drawer(TargetAccepted, _at_position(mark_accepted)),
    ]
)
"""The drawer of each event type with a place on the map, in drawing order (accepted targets on top)."""
DRAW_ORDER = tuple(EVENT_DRAWERS)


def draw_event(draw: Draw, canvas: Canvas, trace: SavedTrace, event: Event) -> None:
    """The marker of one trace event (types without a place on the map draw nothing)."""
    drawer = EVENT_DRAWERS.get(type(event))
    if drawer is not None:
        drawer(draw, canvas, trace, event)


# ---------------------------------------------------------------------------------------------- legend and title


def _legend_entries(success: bool) -> list[tuple[str, Marker]]:
    def path(draw: Draw, px: float, py: float) -> None:
        for k in range(4):
            draw.line([(px - 14 + 7 * k, py), (px - 7 + 7 * k, py)], fill=segment_color(k, 4), width=4)

    def explored(draw: Draw, px: float, py: float) -> None:
        fill = blended(STRUCTURE_COLORS[Material.FREE], EXPLORED_TINT, EXPLORED_ALPHA)
        draw.rectangle([px - 12, py - 7, px + 12, py + 7], fill=fill, outline=(150, 150, 150))

    def decision(draw: Draw, px: float, py: float) -> None:
        mark_decision(draw, (px - 10, py + 5), (px + 6, py - 3), (px + 14, py - 6), label_color(2))

    def goal(draw: Draw, px: float, py: float) -> None:
        draw.rectangle([px - 10, py - 6, px + 10, py + 6], fill=(200, 200, 200), outline=GOAL_OUTLINE, width=3)

    end_color = SUCCESS_COLOR if success else FAILURE_COLOR
    return [
        ("start", lambda d, x, y: mark_pose(d, x, y, 6, 0.0, START_COLOR)),
        ("end (green: success)", lambda d, x, y: mark_pose(d, x, y, 6, 0.0, end_color)),
        ("path, segment 1 ... last", path),
        (EXPLORED_ENTRY, explored),
        ("direction chosen: arrow, goal", decision),
        ("inspection sweep", mark_inspection),
        ("detection", mark_detection),
        ("target accepted", mark_accepted),
        ("target rejected", mark_rejected),
        (GOAL_ENTRY, goal),
        ("view points", lambda d, x, y: _disc(d, x, y, 2.5, VIEW_POINT_COLOR, None)),
        *_floor_entries(),
    ]


def _floor_entries() -> list[tuple[str, Marker]]:
    """The legend of what only a building's maps show."""

    def stairs(draw: Draw, px: float, py: float) -> None:
        fill = blended(STRUCTURE_COLORS[Material.FREE], STAIRS_TINT, STAIRS_ALPHA)
        draw.rectangle([px - 12, py - 7, px + 12, py + 7], fill=fill, outline=TREAD_COLOR)
        for x in (px - 6, px, px + 6):
            draw.line([(x, py - 7), (x, py + 7)], fill=TREAD_COLOR, width=1)

    def hole(draw: Draw, px: float, py: float) -> None:
        draw.rectangle([px - 12, py - 7, px + 12, py + 7], fill=HOLE_COLOR)

    def railing(draw: Draw, px: float, py: float) -> None:
        draw.rectangle([px - 12, py - 2, px + 12, py + 2], fill=RAILING_COLOR)

    def changes(draw: Draw, px: float, py: float) -> None:
        mark_floor_change(draw, px - 8, py, True, leaving=True)
        mark_floor_change(draw, px + 10, py, True, leaving=False)

    return list(zip(FLOOR_ENTRIES, (stairs, hole, railing, changes), strict=True))


EXPLORED_ENTRY = "explored (approx., 5 m HFOV)"
GOAL_ENTRY = "goal object"
FLOOR_ENTRIES = (
    "stairs up from this floor",
    "stairwell (open below)",
    "railing",
    "path leaves / enters the floor",
)


def add_legend(
    image: Image.Image,
    success: bool,
    omit: frozenset[str] = frozenset(),
    extra: Sequence[tuple[str, Marker]] = (),
) -> Image.Image:
    """The picture with a legend panel on its right (without the entries named in ``omit``: what was not drawn;
    with the ``extra`` entries of a plug-in's events)."""
    entries = [entry for entry in _legend_entries(success) if entry[0] not in omit] + list(extra)
    height = max(image.height, HEADER + 26 * (len(entries) + 1))
    panel = Image.new("RGB", (image.width + LEGEND_WIDTH, height), (255, 255, 255))
    panel.paste(image, (0, 0))
    draw = ImageDraw.Draw(panel)
    x = image.width + 12
    draw.text((x, HEADER + 4), "legend", fill=(0, 0, 0), font=FONT)
    for row, (text, mark) in enumerate(entries, start=1):
        y = HEADER + 12 + 26 * row
        mark(draw, x + 16, y)
        draw.text((x + 40, y), text, fill=(0, 0, 0), anchor="lm", font=SMALL_FONT)
    return panel


def title(episode: Episode, record: EpisodeRecord | None) -> str:
    text = f"episode {episode.episode_id}  {episode.scene_id}  target: '{episode.object_category}'"
    if record:
        text += (
            f"  success={record.success}  SPL={shown(record.spl, '{:.2f}')}"
            f"  steps={record.steps}  stop={record.stop_reason}"
        )
    return text


def draw_trace(
    draws: Sequence[Draw],
    canvas: Canvas,
    trace: SavedTrace,
    floors: NDArray[np.int64],
    success: bool,
    specs: plugin_events.Specs | None = None,
) -> None:
    """A whole trace on the floors' maps (``draws``: per floor, its map; ``floors``: per pose, its floor): on each
    floor its part of the path, where the path leaves and enters it, the events at its poses (a plug-in's as
    ``specs`` declare them, :mod:`~drivenav.viz.plugin_events`), the start and the end when they are on it."""
    moves = move_floors(floors)
    for index, draw in enumerate(draws):
        draw_trajectory(draw, canvas, trace, moves == index)
    for move in floor_changes(floors):
        draw_floor_change(draws, canvas, trace, floors, move)
    for kind in DRAW_ORDER:
        for event in trace.of_type(kind):
            draw_event(draws[floors[trace.index(event.step)]], canvas, trace, event)
    for event in plugin_events.foreign_events(trace.events):
        spec = plugin_events.spec_of(event, specs or {})
        px, py = canvas.to_pixel(*plugin_events.place(event, spec, trace))
        draw = draws[floors[trace.index(event.step)]]
        plugin_events.mark(draw, px, py, spec)
        draw.text((px + 9, py - 9), spec.legend, fill=darker(spec.color, 0.7), font=SMALL_FONT)
    draw_pose(draws[floors[0]], canvas, trace.xy(0), trace.start.yaw, START_COLOR)
    last = trace.pose(len(trace) - 1)
    draw_pose(draws[floors[-1]], canvas, (last.x, last.y), last.yaw, SUCCESS_COLOR if success else FAILURE_COLOR)


def floor_heading(floor: Floor, episode: Episode, start: bool) -> str:
    """A storey's map title: the floor, and whether the episode starts (``start``) or has goals on it."""
    here = ["start"] if start else []
    if any(floor.holds(z) for *_, z in episode.view_points_xyz()):
        here.append("goal")
    return floor.title + (f": {', '.join(here)}" if here else "")


def draw_episode(
    world: Scene | Building,
    episode: Episode,
    trace: SavedTrace,
    record: EpisodeRecord | None = None,
    explored: Sequence[NDArray[np.bool_]] | None = None,
) -> Image.Image:
    """Top-down picture of one episode with its trace and a legend; ``explored``: per floor, its explored cells.
    A building gets one map per storey, side by side from the ground floor up, under the episode's title."""
    floors = floors_of(world)
    several = len(floors) > 1
    canvas = Canvas(world, FLOOR_SIDE if several else MAX_SIDE)
    maps = [draw_floor(f, episode, canvas, None if explored is None else explored[f.index]) for f in floors]
    draws = [ImageDraw.Draw(image) for image in maps]
    on = pose_floors(world, trace)
    success = bool(record and record.success)
    specs = plugin_events.declared_events(record)
    draw_trace(draws, canvas, trace, on, success, specs)
    headings = [floor_heading(f, episode, f.index == on[0]) for f in floors] if several else [title(episode, record)]
    for draw, heading in zip(draws, headings, strict=True):
        draw.text((6, 7), heading, fill=(0, 0, 0), font=FONT)
    image = maps[0]
    if several:
        row = beside(maps)
        image = stack([_heading_strip(title(episode, record), row.width), row])
    omit = ({EXPLORED_ENTRY} if explored is None else set()) | (set() if several else set(FLOOR_ENTRIES))
    goal_ids = {goal.object_id for goal in episode.goals}
    if not any(obj.instance_id in goal_ids for floor in floors for obj in floor.plan.objects):
        omit.add(GOAL_ENTRY)  # e.g. a Habitat run drawn on a blank floor: goals show as view points only
    extra = plugin_events.legend(plugin_events.foreign_events(trace.events), specs)
    return add_legend(image, success, frozenset(omit), extra)


def _heading_strip(text: str, width: int) -> Image.Image:
    """A white band of one header's height with ``text`` on it."""
    strip = Image.new("RGB", (width, HEADER), (255, 255, 255))
    ImageDraw.Draw(strip).text((6, 7), text, fill=(0, 0, 0), font=FONT)
    return strip


def stack(images: Sequence[Image.Image], background: RGB = (255, 255, 255)) -> Image.Image:
    """Images one under the other, left-aligned."""
    out = Image.new("RGB", (max(i.width for i in images), sum(i.height for i in images)), background)
    y = 0
    for image in images:
        out.paste(image, (0, y))
        y += image.height
    return out


def beside(images: Sequence[Image.Image], gap: int = FLOOR_GAP, background: RGB = (255, 255, 255)) -> Image.Image:
    """Images side by side, ``gap`` pixels apart, top-aligned."""
    width = sum(i.width for i in images) + gap * (len(images) - 1)
    out = Image.new("RGB", (width, max(i.height for i in images)), background)
    x = 0
    for image in images:
        out.paste(image, (x, 0))
        x += image.width + gap
    return out


def save_png(image: Image.Image, path: str | Path) -> Path:
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    image.save(target)
    return target
